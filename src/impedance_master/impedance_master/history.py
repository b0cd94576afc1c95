"""The project's default environment model (`make_identifier`), learned from the WHOLE
history of the slave's data.

Exponentially weighted least squares with a long memory (`HistoryParams.memory` s of motion)
of the table kind of `impedance.Impedance`: static force, Coulomb and breakaway friction and
viscous drag as functions of inserted length on a grid, Dahl friction states for direction
and presliding (their presliding length chosen by the data among `HistoryParams.sigmas`:
stiff catheters reverse their friction within a fraction of a millimetre, compliant shafts
and vessel beds over millimetres), the mass term. Smoothness priors make unvisited grid
nodes extrapolate from visited ones (friction linearly, static force flat); parameters are
physically bounded (friction, breakaway and drag >= 0, a static force that never pulls the
catheter in, a mass of grams) by an active-set solve (`history_prior`). Samples at rest are not
learned from
(the model is held). Forgetting, priors and bounds make the solve well posed whatever the
data: the matrix is the data's information plus a positive definite prior, never singular.

Bounded influence: physically impossible samples are refused before they touch any state
(`gating.SampleGate`: counted in `n_rejected` / `rejected`); the measured force enters the
fit clipped to the current model's prediction +- a robust band (`HistoryParams.clip_*`,
counted in `n_clipped`), so one outlier sample of any size moves the fit as one sample with
a residual of at most that band would. A model outside the `envelope` is not published
(status 'out_of_envelope', the previous model is held).

Each published model carries an `impedance.Anchor`: the slave's state, measured force and
low-passed residual at the sample it was made at. Before the first model (status 'filling')
every `solve_every` samples yields an INVALID linear model that carries only the anchor
(residual 0): no model to render, but where the slave has been and what force it met there
(nineteenth round of issue 12: a renderer that counted only the models' anchors did not
know the first second of the insertion, where a wall's onset often is).
"""
from __future__ import annotations

import math
from dataclasses import fields, replace
from typing import Optional

import numpy as np
from scipy.linalg import get_lapack_funcs

from catheter_common.checks import finite, positive
from impedance_master.envelope import DEFAULT_ENVELOPE, ModelEnvelope
from impedance_master.filters import Differentiator
from impedance_master.gating import Despiker, SampleGate
from impedance_master.history_params import HistoryParams
from impedance_master.history_prior import build_prior, candidate_index, n_params
from impedance_master.impedance import Anchor, FrictionState, Impedance, steady_states


class HistoryIdentifier:
    """The project's default environment model, learned from the whole history (see module doc).

    Args:
        window: s; only sets how much motion (window * rate moving samples) is needed before
            the first model is declared valid.
        rate: Hz, sample rate.
        params: a `HistoryParams` (None: the defaults); keyword overrides of its fields may
            be given directly (``HistoryIdentifier(memory=30.0)``).
        gate: the `SampleGate` refusing impossible samples (None: the default gate).
        envelope: the `ModelEnvelope` a model must satisfy to be published (None: the default).
    Every field of the params is also an attribute (``ident.memory``), read-only by
    convention; `params` holds them all.
    Attributes after update: `status` ('filling', 'ok', 'at_rest', 'out_of_envelope',
    'ill_conditioned'), `n_samples`, `n_moving`, `n_solves`, `n_held`, `n_rejected` and
    `rejected` (from the gate), `n_clipped` (forces clipped to the robust band),
    `n_bursts` and `n_burst_samples` (runs of forces outside that band shorter than
    `burst_samples`, dropped as sensor bursts),
    `n_out_of_envelope`, `scale` (N, running mean absolute residual), `last`.
    """

    STATE_VERSION = 2
    #: the lazy forgetting scale is folded back into the stored matrix below this
    _G_MIN = 1e-30

    def __init__(self, window: float = 1.0, rate: float = 1000.0,
                 params: Optional[HistoryParams] = None, gate: Optional[SampleGate] = None,
                 envelope: Optional[ModelEnvelope] = None, **overrides):
        self.window = positive('window', window)
        self.rate = positive('rate', rate)
        if params is None:
            params = HistoryParams()
        if not isinstance(params, HistoryParams):
            raise ValueError(f'params must be a HistoryParams, got {type(params).__name__}')
        unknown = sorted(set(overrides) - set(HistoryParams.names()))
        if unknown:
            raise ValueError(f'unknown HistoryIdentifier parameter {unknown[0]!r} (see '
                             'HistoryParams)')
        p = replace(params, **overrides) if overrides else params
        self.params = p
        for f in fields(p):
            setattr(self, f.name, getattr(p, f.name))
        if gate is not None and not isinstance(gate, SampleGate):
            raise ValueError(f'gate must be a SampleGate, got {type(gate).__name__}')
        self.gate = gate if gate is not None else SampleGate(rate=self.rate)
        if envelope is not None and not isinstance(envelope, ModelEnvelope):
            raise ValueError(f'envelope must be a ModelEnvelope, got {type(envelope).__name__}')
        self.envelope = envelope if envelope is not None else DEFAULT_ENVELOPE
        self.dx = p.dx
        self._nodes = self.x_min + self.dx * np.arange(self.n_nodes)
        self.P = n_params(p)
        self._K = len(self.sigmas)
        self._cand = [candidate_index(p, k) for k in range(self._K)]
        # scales of the feature columns: velocity by V, acceleration by A (coefficients in N)
        self._V = 0.04
        self._A = 1.0
        P, G = self.P, self.n_nodes
        # flat indices (into the raveled P x P matrix) of each candidate's block: one `take`
        # instead of np.ix_ per solve (the same values, ~4 us against ~35 us)
        self._cand_flat = [(i[:, None] * P + i).ravel() for i in self._cand]
        # flat indices of the diagonal entries of each candidate's S and C nodes (`_model`)
        self._diag_sc = [np.concatenate([i[:G], i[3 * G:4 * G]]) * (P + 1) for i in self._cand]
        self._tab_div = np.array([[1.0], [1.0], [1.0], [self._V]])
        # a sample's row has 2 nonzeros per table block (nodes j, j + 1) and the mass: its
        # positions per cell j, and their flat indices into the P x P matrix
        nb = 2 + 2 * self._K
        self._row_pos = [np.append((np.arange(nb)[:, None] * G + [j, j + 1]).ravel(), P - 1)
                         for j in range(G - 1)]
        self._row_flat = [(q[:, None] * P + q).ravel() for q in self._row_pos]
        self._lam = math.exp(-1.0 / (self.memory * self.rate))
        self._prior, self._lo, self._hi = build_prior(p, self._A)
        # per candidate: its prior block and bounds (constant), for the solves
        self._cand_prior = [self._prior[np.ix_(i, i)] for i in self._cand]
        self._cand_lo = [self._lo[i] for i in self._cand]
        self._cand_hi = [self._hi[i] for i in self._cand]
        self._res_alpha = (1.0 - math.exp(-1.0 / (self.residual_time * self.rate))
                           if self.residual_time > 0.0 else 1.0)
        self._scale_alpha = 1.0 - math.exp(-1.0 / (self.scale_time * self.rate))
        self.reset()

    def reset(self) -> None:
        """Forget everything learned (the gate's counters too)."""
        # the normal equations (A, b) are kept as g * (_A_s, _b_s): the forgetting scales the
        # scalar g, a batch's rows are added at its flush divided by g (`_flush`)
        self._A_s = np.zeros((self.P, self.P))
        self._b_s = np.zeros(self.P)
        self._g = 1.0
        # the current batch's rows as they arrive, per grid cell j (lists of the row's
        # nonzeros in `_row_pos[j]` order, with the force appended); `_flush` sums each
        # cell's rows with one matrix product
        self._batch: list = [[] for _ in range(self.n_nodes - 1)]
        self._touched: list = []          # cells j with rows in the batch, in arrival order
        self._rows = 0
        self._moving_in_batch = 0
        self._since_solve = 0
        self._zs = [FrictionState(sg, self.v_s, self.beta) if sg > 0.0 else None
                    for sg in self.sigmas]
        self.selected = self.sigmas.index(self.sigma)     # the rendered candidate

        self._last_k = self.selected                      # the candidate of `last`
        self.n_selections = 0
        self.n_outward = 0        # moving samples learned retracting (up to select_outward)
        self._da = Differentiator(self.rate)      # x'' from x' when not given
        self.gate.reset()
        self._despike = Despiker()
        self.n_samples = 0
        self.n_moving = 0
        self.n_solves = 0
        self.n_held = 0
        self.n_clipped = 0
        self.n_bursts = 0
        self.n_burst_samples = 0
        self._held: list = []        # samples outside the robust band, not yet learned
        self._burst_confirmed = False
        self.n_out_of_envelope = 0
        self.status = 'filling'
        self.theta = np.zeros(self.P)
        self.last: Optional[Impedance] = None
        self._sample = None          # (x, xd, xdd, zs, f) of the latest sample
        self._filling: Optional[Impedance] = None   # the latest anchor-only model (filling)
        self._res = 0.0              # low-passed residual f - model at the slave's state
        self.scale = self.clip_floor / max(self.clip_factor, 1.0)
        self.envelope_reason: Optional[str] = None

    @property
    def n_rejected(self) -> int:
        return self.gate.n_rejected

    @property
    def rejected(self) -> dict:
        return dict(self.gate.rejected)

    # ------------------------------------------------------------------ persistence
    def get_state(self) -> dict:
        """The learned information (normal equations of every friction bank) and the
        selected presliding length as plain JSON-able values."""
        self._flush()
        return {'version': self.STATE_VERSION, 'kind': 'HistoryIdentifier',
                'grid': _json_ready(self), 'n_moving': int(self.n_moving),
                'selected': int(self.selected), 'n_outward': int(self.n_outward),
                'A': self.information().tolist(), 'b': (self._b_s * self._g).tolist()}

    def information(self) -> np.ndarray:
        """The data's information matrix A (P x P, flushed batches only; a copy)."""
        return self._A_s * self._g

    def _parse_state(self, state) -> dict:
        """The validated arrays of a `get_state()` dict (ValueError naming what is wrong)."""
        if not isinstance(state, dict) or state.get('kind') != 'HistoryIdentifier':
            raise ValueError('state must be a dict from HistoryIdentifier.get_state()')
        if state.get('version') != self.STATE_VERSION:
            raise ValueError(f'state version must be {self.STATE_VERSION}, '
                             f'got {state.get("version")!r}')
        grid = state.get('grid')
        if not isinstance(grid, dict):
            raise ValueError('state grid must be a dict')
        for k, v in _json_ready(self).items():
            try:
                same = k in grid and math.isclose(float(grid[k]), float(v), rel_tol=1e-12)
            except (TypeError, ValueError):
                same = False
            if not same:
                raise ValueError(f'state grid {k}={grid.get(k)!r} differs from this '
                                 f'identifier\'s {v!r}')
        out = {}
        for name, shape in (('A', (self.P, self.P)), ('b', (self.P,))):
            try:
                a = np.asarray(state.get(name), dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f'state {name} must be a numeric array') from None
            if a.shape != shape:
                raise ValueError(f'state {name} must have shape {shape}, got {a.shape}')
            if not np.all(np.isfinite(a)):
                raise ValueError(f'state {name} must be finite')
            if a.ndim == 2:
                a = 0.5 * (a + a.T)
                if np.linalg.eigvalsh(a).min() < -1e-9 * max(1.0, float(np.abs(a).max())):
                    raise ValueError(f'state {name} must be positive semi-definite (an '
                                     'information matrix)')
            out[name] = a
        n = state.get('n_moving')
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f'state n_moving must be an int >= 0, got {n!r}')
        k = state.get('selected')
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < self._K:
            raise ValueError(f'state selected must be an int in 0..{self._K - 1}, got {k!r}')
        out['n_moving'], out['selected'] = n, k
        # a state written before the fifteenth round has no count: its data were learned
        # over a whole motion, both ways, so it counts as complete
        no = state.get('n_outward', self.select_outward)
        if isinstance(no, bool) or not isinstance(no, int) or no < 0:
            raise ValueError(f'state n_outward must be an int >= 0, got {no!r}')
        out['n_outward'] = min(no, self.select_outward)
        return out

    def _install(self, arrays: dict) -> Optional[Impedance]:
        self.reset()
        self._A_s, self._b_s, self._g = arrays['A'].copy(), arrays['b'].copy(), 1.0
        self.n_moving, self.selected = arrays['n_moving'], arrays['selected']
        self.n_outward = arrays['n_outward']
        self._last_k = self.selected
        if self.n_moving < self.window * self.rate:
            return None
        return self._solve(moved=True)

    def set_state(self, state: dict) -> Optional[Impedance]:
        """Continue from `get_state()` output (same grid and friction hyper-parameters);
        returns the model solved from it (None if it holds too little motion).
        ValueError, and nothing changed, if the state is malformed, of another version or
        grid, not finite, not an information matrix, or gives no model inside the envelope
        (a tampered file)."""
        arrays = self._parse_state(state)
        probe = HistoryIdentifier(window=self.window, rate=self.rate, params=self.params,
                                  envelope=self.envelope)
        probe._install(arrays)
        if probe.n_moving >= self.window * self.rate and probe.status != 'ok':
            raise ValueError(f'state gives no usable model ({probe.status}: '
                             f'{probe.envelope_reason})')
        return self._install(arrays)

    def save_state(self, path: str) -> None:
        """Write `get_state()` atomically (see `state_file.write_state`)."""
        from impedance_master.state_file import write_state
        write_state(path, self.get_state())

    def load_state(self, path: str) -> Optional[Impedance]:
        """Read a JSON file written by `save_state` and continue from it (ValueError if it
        is unreadable or rejected; see `set_state`)."""
        from impedance_master.state_file import read_state
        return self.set_state(read_state(path))

    # ------------------------------------------------------------------ samples
    def update(self, x: float, xd: float, xdd: Optional[float], f: float) -> Optional[Impedance]:
        """Add one sample (x m, x' m/s, x'' m/s^2 or None, measured force f N).

        x'' None: the backward difference of x' at `rate` (what a node fed a JointState, which
        has no acceleration field, passes; the simulated robot's x'' is exactly that
        difference). Leaving it at 0 instead removes the mass column from the fit, which
        doubled the outage error of the ROS graph against the pure experiment.
        Non-finite values: ValueError naming the argument. Impossible samples (see
        `gating.SampleGate`) are counted and ignored.

        Returns None before the first sample at a `solve_every` tick; until `window`
        seconds of motion have been seen, an invalid anchor-only model (status 'filling',
        `_filling_model`); then the latest model (a new one every `solve_every` samples;
        the same object in between).
        """
        x = finite('x', x)
        xd = finite('xd', xd)
        xdd_in = None if xdd is None else finite('xdd', xdd)
        f = finite('f', f)
        if self.gate.check(x, xd, xdd_in, f) is not None:
            return self._tick()         # refused: learned from nothing, the cadence goes on
        if self.gate.resync:                 # the axis really moved there: restart the states
            for st in self._zs:
                if st is not None:
                    st.reset(x, st.z1, st.z2)
            self._da = Differentiator(self.rate)
            self._despike.reset((x, xd, xdd_in, f))
            self._held = []                   # held from before the jump: not learned
            self._burst_confirmed = False
        x, xd, xdd_in, f = self._despike(x, xd, xdd_in, f)
        xdd_diff = self._da(xd)
        xdd = xdd_diff if xdd_in is None else xdd_in
        zs = [st.update(x, xd) if st is not None else steady_states(xd, self.v_s, self.beta)
              for st in self._zs]
        z = zs[self._last_k]
        self.n_samples += 1
        model = self.last
        if model is not None and model.valid:
            pred = model.force(x, xd, xdd, z)
            band = self._band()
            if self.clip_factor > 0.0 and self.burst_samples > 0:
                if abs(f - pred) > band:
                    if not self._burst_confirmed:
                        self._held.append((x, xd, xdd, zs, f, pred))
                        if len(self._held) <= self.burst_samples:
                            return self._tick()     # a sensor burst or a real change: wait
                        self._burst_confirmed = True    # it persists: a real change
                        held, self._held = self._held, []
                        for smp in held:
                            self._learn(*smp, self._band())
                        return self._tick()
                else:
                    if self._held:              # it ended within burst_samples: a burst
                        self.n_bursts += 1
                        self.n_burst_samples += len(self._held)
                        self._held = []
                    self._burst_confirmed = False
            self._learn(x, xd, xdd, zs, f, pred, band)
        else:
            self._learn(x, xd, xdd, zs, f, None, 0.0)
        return self._tick()

    def _band(self) -> float:
        """N, half-width of the robust band about the model's prediction."""
        return max(self.clip_floor, self.clip_factor * self.scale)

    def _learn(self, x, xd, xdd, zs, f, pred, band) -> None:
        """Learn one accepted sample: its force clipped to the robust band (`_band()`, N)
        about `pred` (the model's prediction at the sample; None: no model yet, learned as
        measured), the residual's scale and low-pass, the latest sample (the next anchor),
        its row if moving."""
        if pred is not None:
            r = f - pred
            if self.clip_factor > 0.0 and abs(r) > band:
                self.n_clipped += 1
                r = math.copysign(band, r)
            f_fit = pred + r
            self.scale += self._scale_alpha * (min(abs(r), 3.0 * self.scale + 1e-4)
                                               - self.scale)
            self._res += self._res_alpha * (r - self._res)
        else:
            f_fit = f
        self._sample = (x, xd, xdd, zs, f)
        if abs(xd) >= self.rest_velocity:
            self._add_row(x, xd, xdd, zs, f_fit)
            if xd < 0.0 and self.n_outward < self.select_outward:
                self.n_outward += 1

    def _tick(self) -> Optional[Impedance]:
        """One sample period: a new model every `solve_every` samples."""
        self._since_solve += 1
        if self._since_solve >= self.solve_every or self._rows >= self.solve_every:
            self._flush()
            self._since_solve = 0
            if self.n_moving >= self.window * self.rate:
                return self._solve(moved=self._moving_in_batch > 0)
            self._filling = self._filling_model()
            return self._filling
        return self.last if self.last is not None else self._filling

    def _filling_model(self) -> Optional[Impedance]:
        """Before the first model: an invalid linear model (m = c = k = offset = 0, status
        'filling') carrying the latest sample as its `Anchor` (residual 0: there is no model
        yet). A renderer does not render it; it counts where the slave was (`ImaRenderer`
        folds these anchors in with the first valid model). None before any sample."""
        smp = self._sample
        if smp is None:
            return None
        x, xd, xdd, zs, f = smp
        z = zs[self.selected]
        return Impedance(0.0, 0.0, 0.0, 0.0, False, status='filling',
                         anchor=Anchor(x, xd, xdd, z[0], z[1], f, 0.0))

    def _add_row(self, x, xd, xdd, zs, f) -> None:
        """Add one sample's row (2 nonzeros per table block at the grid cell of x, linear
        interpolation weights w0, w; the mass) and its force to its cell's batch (summed at
        `_flush`: one matrix product per cell and batch instead of an outer product per
        sample)."""
        G = self.n_nodes
        u = (x - self.x_min) / self.dx
        if u <= 0.0:
            j, w = 0, 0.0
        elif u >= G - 1:
            j, w = G - 2, 1.0
        else:
            j = int(u)
            w = u - j
        w0 = 1.0 - w
        row = [w0, w]                # in `_row_pos[j]` order: S, (F_k, B_k) per bank, C, mass
        for z1, z2 in zs:
            dz = z2 - z1
            row += (w0 * z1, w * z1, w0 * dz, w * dz)
        vz = xd / self._V
        row += (w0 * vz, w * vz, xdd / self._A, f)
        rows = self._batch[j]
        if not rows:
            self._touched.append(j)
        rows.append(row)
        self._rows += 1
        self.n_moving += 1

    def _flush(self) -> None:
        """End the batch: A <- lam^k A + (the batch's rows' V^T V), b likewise, k its rows (the
        rows of one batch are not forgotten against each other). Lazily: the scale g takes
        the forgetting, the batch's cell sums are added divided by g; g is folded back into
        the stored matrix when it falls below `_G_MIN`."""
        k = self._rows
        self._moving_in_batch = k
        if k == 0:
            return
        g = self._g * self._lam ** k
        flat = self._A_s.reshape(-1)
        for j in self._touched:
            rows = np.array(self._batch[j])
            v = rows[:, :-1]
            vt = v.T
            flat[self._row_flat[j]] += (vt @ v).reshape(-1) / g
            self._b_s[self._row_pos[j]] += (vt @ rows[:, -1]) / g
            self._batch[j] = []
        self._touched.clear()
        if g < self._G_MIN:
            self._A_s *= g
            self._b_s *= g
            g = 1.0
        self._g = g
        self._rows = 0

    # ------------------------------------------------------------------ solve
    def _hold(self, status: str) -> Optional[Impedance]:
        self.status = status
        self.n_held += 1
        if self.last is None:
            return Impedance(valid=False, status=status)
        return self.last

    def _solve_candidate(self, k: int, bound: Optional[float] = None):
        """(theta of candidate k in Impedance order, penalised objective): solve, clamp the
        parameters outside their bounds, re-solve the others, at most 4 rounds (bounds once
        clamped stay clamped: the tuned behaviour of the default; then clipped into the
        box).

        bound: if given, and the unconstrained optimum's objective (a lower bound of the
        clamped one: the objective is convex, its matrix positive definite) is not below it,
        (None, that lower bound) is returned without the clamp rounds."""
        n = self._cand[k].size
        M = self._A_s.take(self._cand_flat[k]).reshape(n, n)
        M *= self._g
        M += self._cand_prior[k]
        b = self._b_s.take(self._cand[k])
        b *= self._g
        lo, hi = self._cand_lo[k], self._cand_hi[k]
        theta, chol = _spd_solve(M, b)
        if bound is not None and chol:
            f0 = float(theta @ M @ theta - 2.0 * b @ theta)
            if f0 >= bound:
                return None, f0
        # a clamped parameter sits on its bound, so only free ones can be outside the box:
        # clipping the whole vector clamps exactly the ones outside
        free = np.ones(n, dtype=bool)
        for _ in range(3):
            bad = (theta < lo) | (theta > hi)
            if not bad.any():
                break
            np.maximum(theta, lo, out=theta)
            np.minimum(theta, hi, out=theta)
            free &= ~bad
            Mf = M[free]
            fixed = ~free
            rhs = b[free] - Mf[:, fixed] @ theta[fixed]
            theta[free] = _spd_solve(Mf[:, free], rhs)[0]
        np.maximum(theta, lo, out=theta)
        np.minimum(theta, hi, out=theta)
        return theta, float(theta @ M @ theta - 2.0 * b @ theta)

    def _select(self) -> dict:
        """Render the candidate presliding length whose penalised fit is best, if it beats
        the current one by more than select_margin residual variances. Returns the solves
        made ({k: (theta, objective)}; the current candidate's always).

        The same decision as solving every candidate: a candidate whose unconstrained
        optimum does not beat the current fit by the margin cannot beat it clamped (its
        clamped objective is at least the unconstrained one), so its clamp rounds are
        skipped (with a slack of 1e-9 relative for the objectives' round-off)."""
        cur = self.selected
        solved = {cur: self._solve_candidate(cur)}
        if self._K == 1:
            return solved
        obj_cur = solved[cur][1]
        var = (1.25 * self.scale) ** 2
        need = obj_cur - self.select_margin * var
        objs = [math.inf] * self._K
        objs[cur] = obj_cur
        early = self.n_outward < self.select_outward     # the stateless law not yet
        for k in range(self._K):
            if k != cur and not (early and self.sigmas[k] == 0.0):
                theta, obj = self._solve_candidate(
                    k, bound=need + 1e-9 * (abs(obj_cur) + abs(need)) + 1e-12)
                if theta is not None:
                    solved[k] = (theta, obj)
                    objs[k] = obj
        best = int(np.argmin(objs))
        if best != cur and objs[cur] - objs[best] > self.select_margin * var:
            self.selected = best
            self.n_selections += 1
        return solved

    def _solve(self, moved: bool) -> Optional[Impedance]:
        if not moved and self.last is not None:
            self.status = 'at_rest'
            self.n_held += 1
            self.last.status = 'at_rest'
            return self.last
        solved = self._select() if self.n_solves % self.select_every == 0 else {}
        done = solved.get(self.selected)
        theta = done[0] if done is not None else self._solve_candidate(self.selected)[0]
        if not np.all(np.isfinite(theta)):
            return self._hold('ill_conditioned')
        new = self._model(theta)
        self.envelope_reason = self.envelope.check(new)
        if self.envelope_reason is not None:
            self.n_out_of_envelope += 1
            return self._hold('out_of_envelope')
        self.theta = theta
        self.n_solves += 1
        self.status = 'ok'
        smp = self._sample
        if smp is not None:
            x, xd, xdd, zs, f = smp
            z = zs[self.selected]
            m_new = new.force(x, xd, xdd, z)
            if self.last is not None and self.last.valid:   # the residual w.r.t. the new model
                self._res += self.last.force(x, xd, xdd, zs[self._last_k]) - m_new
            else:
                self._res = f - m_new
            new.anchor = Anchor(x, xd, xdd, z[0], z[1], f, self._res)
        self.last = new
        self._last_k = self.selected
        return new

    def _model(self, theta: np.ndarray) -> Impedance:
        """The Impedance of a candidate's parameters (S, F, B, C, mass). The linear part goes
        in m, c, k, offset (the thesis's terms): the straight line through the static table
        and the mean drag, weighted by how much data each node has seen; the tables keep
        the rest, so force() is unchanged on the grid (outside it the linear part continues
        while the tables hold their end values)."""
        G = self.n_nodes
        T = theta[:4 * G].reshape(4, G) / self._tab_div       # S, F, B, C (C in N s/m)
        info = self._A_s.take(self._diag_sc[self.selected])    # data on the S and C nodes
        info *= self._g
        info += 1e-9
        k, off = _line(self._nodes, T[0], info[:G])
        wc = info[G:]
        c = float(np.sum(wc * T[3]) / np.sum(wc))
        T[0] -= k * self._nodes + off
        T[3] -= c
        if not np.isfinite(T).all():
            raise ValueError('S, F, B, C must be finite')
        imp = Impedance(float(theta[-1]) / self._A, c, k, off, True, x0=self.x_min, dx=self.dx,
                        sigma=self.sigmas[self.selected], v_s=self.v_s, beta=self.beta,
                        status='ok')
        imp.S, imp.F, imp.B, imp.C = T.tolist()
        return imp


_POTRF, _POTRS = get_lapack_funcs(('potrf', 'potrs'), (np.zeros(1),))


def _spd_solve(M: np.ndarray, b: np.ndarray):
    """(x solving M x = b, True) for a symmetric positive definite M: Cholesky by LAPACK's
    potrf / potrs (what scipy's cho_factor / cho_solve call, here on the lower triangle and
    without their checks); (LU's x, False) if M is not positive definite. An empty system
    (every parameter clamped) has the empty solution."""
    if b.size == 0:
        return b.copy(), True
    c, info = _POTRF(M.T, lower=1, overwrite_a=0, clean=0)   # M.T: Fortran order, no copy
    if info == 0:
        x, info = _POTRS(c, b, lower=1)
        if info == 0:
            return x, True
    return np.linalg.solve(M, b), False


def _line(x: np.ndarray, y: np.ndarray, w: np.ndarray):
    """(slope, intercept) of the least-squares line through (x, y) with weights w."""
    sw = float(w.sum())
    mx = float(w @ x) / sw
    my = float(w @ y) / sw
    dx = x - mx
    wdx = w * dx
    sxx = float(wdx @ dx)
    k = float(wdx @ (y - my)) / sxx if sxx > 0.0 else 0.0
    return k, my - k * mx


def _json_ready(ident: HistoryIdentifier) -> dict:
    d = {'x_min': ident.x_min, 'x_max': ident.x_max, 'n_nodes': ident.n_nodes,
         'v_s': ident.v_s, 'beta': ident.beta, 'n_sigmas': len(ident.sigmas)}
    d.update({f'sigma{i}': v for i, v in enumerate(ident.sigmas)})
    return d
