"""The project's default environment model (`make_identifier`), learned from the WHOLE
history of the slave's data.

Exponentially weighted least squares with a long memory (`HistoryParams.memory` s of motion)
of the table kind of `impedance.Impedance`: static force, Coulomb and breakaway friction and
viscous drag as functions of inserted length on a grid, a Dahl friction state for direction
and presliding, the mass term. Smoothness priors make unvisited grid nodes extrapolate from
visited ones (friction linearly, static force flat); parameters are physically bounded
(friction, breakaway and drag >= 0, a static force that never pulls the catheter in, a mass
of grams) by an active-set solve. Samples at rest are not learned from (the model is held).
Forgetting, priors and bounds make the solve well posed whatever the data: the matrix is
the data's information plus a positive definite prior, never singular.
"""
from __future__ import annotations

import math
from dataclasses import fields, replace
from typing import Optional

import numpy as np

from catheter_common.checks import finite, positive
from impedance_master.filters import Differentiator
from impedance_master.history_params import HistoryParams
from impedance_master.impedance import FrictionState, Impedance


class HistoryIdentifier:
    """The project's default environment model, learned from the whole history (see module doc).

    Args:
        window: s; only sets how much motion (window * rate moving samples) is needed before
            the first model is declared valid.
        rate: Hz, sample rate.
        params: a `HistoryParams` (None: the defaults); keyword overrides of its fields may
            be given directly (``HistoryIdentifier(memory=30.0)``).
    Every field of the params is also an attribute (``ident.memory``), read-only by
    convention; `params` holds them all.
    """

    def __init__(self, window: float = 1.0, rate: float = 1000.0,
                 params: Optional[HistoryParams] = None, **overrides):
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
        self.dx = p.dx
        self._nodes = self.x_min + self.dx * np.arange(self.n_nodes)
        G = self.n_nodes
        self.P = 4 * G + 1
        # scales of the feature columns: velocity by V, acceleration by A (coefficients in N)
        self._V = 0.04
        self._A = 1.0
        self._lam = math.exp(-1.0 / (self.memory * self.rate))
        # second-difference prior on each of the four tables, small ridge on everything
        D = np.zeros((G - 2, G))
        for i in range(G - 2):
            D[i, i:i + 3] = (1.0, -2.0, 1.0)
        DtD = D.T @ D
        D1 = np.zeros((G - 1, G))
        for i in range(G - 1):
            D1[i, i:i + 2] = (-1.0, 1.0)
        D1tD1 = D1.T @ D1
        D3 = np.zeros((G - 3, G))
        for i in range(G - 3):
            D3[i, i:i + 4] = (-1.0, 3.0, -3.0, 1.0)
        D3tD3 = D3.T @ D3
        Pm = np.zeros((self.P, self.P))
        for g in range(4):
            if g == 0:
                blk = self.smoothness * (D1tD1 if self.static_first_difference else DtD)
            else:
                blk = self.friction_smoothness * DtD + self.friction_kink * D3tD3
            Pm[g * G:(g + 1) * G, g * G:(g + 1) * G] = blk
        Pm += 1e-6 * np.eye(self.P)
        # no inserted length, no friction, breakaway or drag: F, B, C vanish at x = 0 (when the
        # grid reaches it). Anchors the friction's slope when only a few mm have been seen
        # (else a static bump can take the rise and friction extrapolates flat)
        if self.origin_weight > 0.0 and self.x_min <= 0.0 <= self.x_max:
            u = -self.x_min / self.dx
            j = min(int(u), G - 2)
            h = np.zeros(G)
            h[j], h[j + 1] = 1.0 - (u - j), u - j
            for g in (1, 2, 3):
                Pm[g * G:(g + 1) * G, g * G:(g + 1) * G] += self.origin_weight * np.outer(h, h)
        # the static table is shrunk toward 0: a force seen in one direction only is
        # attributed to friction (which reverses), the usual case in catheter insertion
        Pm[:G, :G] += self.static_ridge * np.eye(G)
        # the breakaway table is a refinement seen only near reversals and stops: shrink it
        Pm[2 * G:3 * G, 2 * G:3 * G] += self.breakaway_ridge * np.eye(G)
        Pm[3 * G:4 * G, 3 * G:4 * G] += self.viscous_ridge * np.eye(G)
        self._prior = Pm
        lo = np.full(self.P, -np.inf)
        hi = np.full(self.P, np.inf)
        lo[:G], hi[:G] = self.static_min, self.max_force          # S
        lo[G:3 * G] = 0.0                                          # F, B >= 0
        hi[G:3 * G] = self.max_force
        lo[3 * G:4 * G] = 0.0                                      # C >= 0
        lo[4 * G], hi[4 * G] = 0.0, self.max_mass * self._A        # mass
        self._lo, self._hi = lo, hi
        self.reset()

    def reset(self) -> None:
        self._A_mat = np.zeros((self.P, self.P))
        self._b = np.zeros(self.P)
        self._Phi = np.zeros((self.solve_every, self.P))
        self._f = np.zeros(self.solve_every)
        self._rows = 0
        self._moving_in_batch = 0
        self._since_solve = 0
        self._z = FrictionState(self.sigma, self.v_s, self.beta)
        self._da = Differentiator(self.rate)      # x'' from x' when not given
        self.n_samples = 0
        self.n_moving = 0
        self.n_solves = 0
        self.n_held = 0
        self.status = 'filling'
        self.theta = np.zeros(self.P)
        self.last: Optional[Impedance] = None

    # ------------------------------------------------------------------ persistence (JSON)
    STATE_VERSION = 1

    def get_state(self) -> dict:
        """The learned information (normal equations) as plain JSON-able values."""
        self._flush()
        return {'version': self.STATE_VERSION, 'kind': 'HistoryIdentifier',
                'grid': _json_ready(self), 'n_moving': int(self.n_moving),
                'A': self._A_mat.tolist(), 'b': self._b.tolist()}

    def set_state(self, state: dict) -> Optional[Impedance]:
        """Continue from `get_state()` output (same grid and friction hyper-parameters);
        returns the model solved from it (None if it holds too little motion)."""
        if not isinstance(state, dict) or state.get('kind') != 'HistoryIdentifier':
            raise ValueError('state must be a dict from HistoryIdentifier.get_state()')
        if state.get('version') != self.STATE_VERSION:
            raise ValueError(f'state version must be {self.STATE_VERSION}, '
                             f'got {state.get("version")!r}')
        grid = state.get('grid', {})
        mine = _json_ready(self)
        for k, v in mine.items():
            if k not in grid or not math.isclose(float(grid[k]), float(v), rel_tol=1e-12):
                raise ValueError(f'state grid {k}={grid.get(k)!r} differs from this '
                                 f'identifier\'s {v!r}')
        A = np.asarray(state.get('A'), dtype=float)
        b = np.asarray(state.get('b'), dtype=float)
        if A.shape != (self.P, self.P) or b.shape != (self.P,):
            raise ValueError(f'state A must be {self.P}x{self.P} and b {self.P}, got '
                             f'{A.shape} and {b.shape}')
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(b))):
            raise ValueError('state A and b must be finite')
        n = state.get('n_moving')
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise ValueError(f'state n_moving must be an int >= 0, got {n!r}')
        self.reset()
        self._A_mat = 0.5 * (A + A.T)
        self._b = b
        self.n_moving = n
        if n >= self.window * self.rate:
            return self._solve(moved=True)
        return None

    def save_state(self, path: str) -> None:
        """Write `get_state()` as JSON (atomically: temporary file, then rename)."""
        import json
        import os
        tmp = f'{path}.tmp'
        with open(tmp, 'w', encoding='utf-8') as fh:
            json.dump(self.get_state(), fh)
        os.replace(tmp, path)

    def load_state(self, path: str) -> Optional[Impedance]:
        """Read a JSON file written by `save_state` and continue from it."""
        import json
        with open(path, encoding='utf-8') as fh:
            try:
                state = json.load(fh)
            except json.JSONDecodeError as exc:
                raise ValueError(f'path {path!r} is not a JSON state file: {exc}') from None
        return self.set_state(state)

    def update(self, x: float, xd: float, xdd: Optional[float], f: float) -> Optional[Impedance]:
        """Add one sample (x m, x' m/s, x'' m/s^2 or None, measured force f N).

        x'' None: the backward difference of x' at `rate` (what a node fed a JointState, which
        has no acceleration field, passes; the simulated robot's x'' is exactly that
        difference). Leaving it at 0 instead removes the mass column from the fit, which
        doubled the outage error of the ROS graph against the pure experiment.

        Returns None until `window` seconds of motion have been seen, then the latest model
        (a new one every `solve_every` samples; the same object in between).
        """
        x = finite('x', x)
        xd = finite('xd', xd)
        xdd_diff = self._da(xd)
        xdd = xdd_diff if xdd is None else finite('xdd', xdd)
        f = finite('f', f)
        z1, z2 = self._z.update(x, xd)
        self.n_samples += 1
        if abs(xd) >= self.rest_velocity:
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
            dz = z2 - z1
            vz = xd / self._V
            row = self._Phi[self._rows]
            row[j] = w0
            row[j + 1] = w
            row[G + j] = w0 * z1
            row[G + j + 1] = w * z1
            row[2 * G + j] = w0 * dz
            row[2 * G + j + 1] = w * dz
            row[3 * G + j] = w0 * vz
            row[3 * G + j + 1] = w * vz
            row[4 * G] = xdd / self._A
            self._f[self._rows] = f
            self._rows += 1
            self.n_moving += 1
        self._since_solve += 1
        if self._since_solve >= self.solve_every or self._rows >= self.solve_every:
            self._flush()
            self._since_solve = 0
            if self.n_moving >= self.window * self.rate:
                return self._solve(moved=self._moving_in_batch > 0)
            return None
        return self.last

    def _flush(self) -> None:
        k = self._rows
        self._moving_in_batch = k
        if k == 0:
            return
        Phi = self._Phi[:k]
        decay = self._lam ** k
        self._A_mat *= decay
        self._b *= decay
        self._A_mat += Phi.T @ Phi
        self._b += Phi.T @ self._f[:k]
        self._Phi[:k] = 0.0
        self._rows = 0

    def _solve(self, moved: bool) -> Impedance:
        if not moved and self.last is not None:
            self.status = 'at_rest'
            self.n_held += 1
            self.last.status = 'at_rest'
            return self.last
        M = self._A_mat + self._prior
        b = self._b.copy()
        free = np.ones(self.P, dtype=bool)
        theta = np.zeros(self.P)
        for _ in range(4):  # active set: clamp violated bounds, re-solve the rest
            idx = np.flatnonzero(free)
            rhs = b[idx] - M[np.ix_(idx, ~free)] @ theta[~free]
            theta[idx] = np.linalg.solve(M[np.ix_(idx, idx)], rhs)
            bad = free & ((theta < self._lo) | (theta > self._hi))
            if not bad.any():
                break
            theta[bad] = np.clip(theta[bad], self._lo[bad], self._hi[bad])
            free &= ~bad
        theta = np.clip(theta, self._lo, self._hi)
        if not np.all(np.isfinite(theta)):
            self.status = 'ill_conditioned'
            self.n_held += 1
            return self.last if self.last is not None else Impedance(valid=False,
                                                                     status=self.status)
        self.theta = theta
        self.n_solves += 1
        self.status = 'ok'
        G = self.n_nodes
        # report the linear part in m, c, k, offset (the thesis's terms): the straight line
        # through the static table and the mean drag, weighted by how much data each node
        # has seen; the tables keep the rest, so force() is unchanged on the grid (outside
        # it the linear part continues while the tables hold their end values)
        S = theta[:G]
        C = theta[3 * G:4 * G] / self._V
        info = np.diag(self._A_mat)
        w = info[:G] + 1e-9
        k, off = np.polyfit(self._nodes, S, 1, w=np.sqrt(w))
        wc = info[3 * G:4 * G] + 1e-9
        c = float(np.sum(wc * C) / np.sum(wc))
        self.last = Impedance(
            m=float(theta[4 * G]) / self._A, c=c, k=float(k), offset=float(off), valid=True,
            x0=self.x_min, dx=self.dx, sigma=self.sigma, v_s=self.v_s, beta=self.beta,
            S=(S - (k * self._nodes + off)).tolist(), F=theta[G:2 * G].tolist(),
            B=theta[2 * G:3 * G].tolist(), C=(C - c).tolist(), status='ok')
        return self.last


def _json_ready(ident: HistoryIdentifier) -> dict:
    return {'x_min': ident.x_min, 'x_max': ident.x_max, 'n_nodes': ident.n_nodes,
            'sigma': ident.sigma, 'v_s': ident.v_s, 'beta': ident.beta}
