"""Environment models that travel from the slave to the master (DESIGN section 5).

`Impedance` is the model the identifiers produce and the renderer evaluates on the master's
LOCAL trajectory. Two kinds share one class:

* **linear** (thesis Eq. 29 with an offset): ``f = m x'' + c x' + k x + offset``;
* **table** (the project's default, `make_identifier`): the linear terms plus functions of the
  inserted length ``x`` tabulated on a uniform grid of ``n`` nodes (piecewise-linear "hat"
  interpolation, constant outside the grid)::

      f = m x'' + c x' + k x + offset
          + S(x)                                   static force (wall contact, springs)
          + F(x) z1 + B(x) (z2 - z1)               friction: Coulomb level F, breakaway extra B
          + C(x) x'                                viscous drag growing with inserted length

  The default identifier puts the linear part in m, c, k, offset (the thesis's terms: the
  data-weighted straight line through the static force and the mean drag) and the rest in
  the tables, so ``c + C(x) >= 0`` is the drag and ``k x + offset + S(x)`` the static force.

  ``z1`` in [-1, 1] (Dahl) and ``z2`` (LuGre-like, with a breakaway peak of relative height
  ``beta`` below ``v_s``) are friction states driven by the motion (`FrictionState`,
  presliding length ``sigma``): +1 (resp. up to 1 + beta) after inserting by more than a few
  ``sigma``, negative after retracting, in between during a reversal, and they HOLD their
  values at rest, so the model reproduces the friction that a stopped catheter keeps.
  Without states, ``force`` uses the stateless approximation `FrictionState.steady`.

Units: x m, x' m/s, x'' m/s^2, forces N; m kg, c N s/m, k N/m, offset N; S, F, B in N;
C in N s/m; sigma and grid in m; v_s m/s; beta dimensionless.

On the wire (/slave/impedance, a JointState used as named float64 values) the model is
`to_fields()`: the names start with catheter_common.topics.IMPEDANCE_FIELDS
('m', 'c', 'k', 'offset', 'valid'), then 'kind' (0 linear, 1 table) and, for tables,
'x0', 'dx', 'sigma', 'v_s', 'beta', 'n' and the node values 'S0'.., 'F0'.., 'B0'.., 'C0'...
"""
from __future__ import annotations

import math
from typing import Dict, NamedTuple, Optional, Sequence

from catheter_common.checks import finite, nonneg, positive

#: names that always come first on the wire (same tuple as catheter_common.topics)
BASE_FIELDS = ('m', 'c', 'k', 'offset', 'valid')
KIND_LINEAR = 0
KIND_TABLE = 1
MAX_NODES = 256


def steady_states(xd: float, v_s: float, beta: float):
    """The friction states (z1, z2) of steady motion at velocity xd (m/s): z1 = tanh(xd / v_s)
    and z2 = z1 (1 + beta exp(-(xd / v_s)^2)). Also the states of a stateless model
    (sigma = 0), whose friction follows the velocity and vanishes at rest."""
    r = xd / v_s
    z1 = math.tanh(r)
    return z1, z1 * (1.0 + beta * (math.exp(-r * r) if r * r < 700.0 else 0.0))


class FrictionState:
    """Friction states driven by the motion (exact per increment, stable for any step).

    * ``z1`` in [-1, 1], Dahl: ``dz1/dx = (1 - z1 sign(dx)) / sigma``, rate independent;
    * ``z2`` LuGre-like with a breakaway peak: ``dz2/dx = (1 - z2 sign(dx) / g(x')) / sigma``
      with ``g(v) = 1 + beta exp(-(v / v_s)^2)``: steady value g(v) sign(v) (1 + beta when
      sliding slowly, 1 when fast), and like a real bristle it keeps its value at rest.

    Both hold at rest (no displacement), so a stopped catheter keeps the friction it had.

    Args:
        sigma: presliding length in m (> 0).
        v_s: m/s, velocity scale of the breakaway peak; beta: its relative height (>= 0).
    """

    __slots__ = ('sigma', 'v_s', 'beta', 'z1', 'z2', '_x')

    def __init__(self, sigma: float = 3e-4, v_s: float = 0.002, beta: float = 0.5):
        self.sigma = positive('sigma', sigma)
        self.v_s = positive('v_s', v_s)
        self.beta = nonneg('beta', beta)
        self.z1 = 0.0
        self.z2 = 0.0
        self._x: Optional[float] = None

    def key(self) -> tuple:
        """The hyper-parameters that define the states (equal keys: interchangeable)."""
        return self.sigma, self.v_s, self.beta

    def reset(self, x: Optional[float] = None, z1: float = 0.0, z2: float = 0.0) -> None:
        self._x = x
        self.z1 = z1
        self.z2 = z2

    def steady(self, xd: float):
        """Stateless approximation (z1, z2) for steady motion at velocity xd."""
        return steady_states(xd, self.v_s, self.beta)

    def update(self, x: float, xd: float):
        """Advance to position x (m) moving at xd (m/s); return (z1, z2)."""
        xl = self._x
        self._x = x
        if xl is None:
            return self.z1, self.z2
        dx = x - xl
        if dx != 0.0:
            s = self.sigma
            e1 = math.exp(-abs(dx) / s)
            r = xd / self.v_s
            g = 1.0 + self.beta * (math.exp(-r * r) if r * r < 700.0 else 0.0)
            sgn = 1.0 if dx > 0.0 else -1.0
            self.z1 = sgn + (self.z1 - sgn) * e1
            z2s = sgn * g
            self.z2 = z2s + (self.z2 - z2s) * math.exp(-abs(dx) / (s * g))
        return self.z1, self.z2


class Anchor(NamedTuple):
    """Where the model was made: the slave's state and measured force at that sample.

    x m, xd m/s, xdd m/s^2, z1 / z2 the identifier's friction states there, f N the
    measured force, r N the identifier's low-passed residual (measured minus model) there.
    The master may render ``f + model(its state) - model(anchor)`` (model-mediated: the
    model only has to be right about changes) or ``model + r`` near the anchor.
    """
    x: float
    xd: float
    xdd: float
    z1: float
    z2: float
    f: float
    r: float


#: wire names of the anchor fields (in Anchor order)
ANCHOR_FIELDS = tuple('anchor_' + n for n in Anchor._fields)


class Impedance:
    """An environment model: linear impedance plus optional length-tabulated nonlinear terms.

    Args:
        m: kg, c: N s/m, k: N/m, offset: N (finite).
        valid: True when the identifier vouches for the model (False: warming up / holding
            without a good estimate; renderers keep their previous model).
        x0, dx: grid start and spacing in m (table models).
        sigma: presliding length of the friction states in m (0: a stateless model, whose
            friction follows the velocity, `steady_states`, and vanishes at rest); v_s:
            velocity scale in m/s; beta: relative breakaway height of the z2 state (see
            FrictionState).
        S, F, B, C: node values (same length n >= 2), N, N, N, N s/m. None: linear model.
        status: a short reason string from the identifier (not sent on the wire).
        anchor: an `Anchor` (or a sequence in its field order), or None.
    """

    __slots__ = ('m', 'c', 'k', 'offset', 'valid', 'x0', 'dx', 'sigma', 'v_s', 'beta',
                 'S', 'F', 'B', 'C', 'status', 'anchor')

    def __init__(self, m: float = 0.0, c: float = 0.0, k: float = 0.0, offset: float = 0.0,
                 valid: bool = True, *, x0: float = 0.0, dx: float = 0.005,
                 sigma: float = 3e-4, v_s: float = 0.002, beta: float = 0.5,
                 S: Optional[Sequence[float]] = None, F: Optional[Sequence[float]] = None,
                 B: Optional[Sequence[float]] = None, C: Optional[Sequence[float]] = None,
                 status: str = '', anchor: Optional[Sequence[float]] = None):
        self.m = finite('m', m)
        self.c = finite('c', c)
        self.k = finite('k', k)
        self.offset = finite('offset', offset)
        self.valid = bool(valid)
        self.x0 = finite('x0', x0)
        self.dx = positive('dx', dx)
        self.sigma = nonneg('sigma', sigma)
        self.v_s = positive('v_s', v_s)
        self.beta = nonneg('beta', beta)
        self.status = str(status)
        tables = (S, F, B, C)
        if all(t is None for t in tables):
            self.S = self.F = self.B = self.C = None
        else:
            if any(t is None for t in tables):
                raise ValueError('S, F, B, C must be given together (or none of them)')
            n = len(S)
            if n < 2 or n > MAX_NODES:
                raise ValueError(f'S must have 2..{MAX_NODES} nodes, got {n}')
            out = []
            for name, t in zip('SFBC', tables, strict=True):
                if len(t) != n:
                    raise ValueError(f'{name} must have {n} nodes like S, got {len(t)}')
                out.append([finite(f'{name}[{i}]', v) for i, v in enumerate(t)])
            self.S, self.F, self.B, self.C = out
        if anchor is None:
            self.anchor = None
        else:
            if len(anchor) != len(Anchor._fields):
                raise ValueError(f'anchor must have {len(Anchor._fields)} values '
                                 f'{Anchor._fields}, got {len(anchor)}')
            self.anchor = Anchor(*(finite(f'anchor.{n}', v)
                                   for n, v in zip(Anchor._fields, anchor, strict=True)))

    @classmethod
    def from_arrays(cls, m: float, c: float, k: float, offset: float, *, x0: float,
                    dx: float, sigma: float, v_s: float, beta: float, S, F, B, C,
                    status: str = '') -> 'Impedance':
        """A valid table model from numpy arrays (one vectorised finiteness check instead
        of one per node; the identifiers' fast path). ValueError if anything is not finite."""
        import numpy as np
        tabs = [np.asarray(t, dtype=float) for t in (S, F, B, C)]
        n = tabs[0].size
        if any(t.shape != (n,) for t in tabs) or not 2 <= n <= MAX_NODES:
            raise ValueError(f'S, F, B, C must be 1-D of one length in 2..{MAX_NODES}')
        if not all(bool(np.all(np.isfinite(t))) for t in tabs):
            raise ValueError('S, F, B, C must be finite')
        imp = cls(m, c, k, offset, True, x0=x0, dx=dx, sigma=sigma, v_s=v_s, beta=beta,
                  status=status)
        imp.S, imp.F, imp.B, imp.C = (t.tolist() for t in tabs)
        return imp

    # ------------------------------------------------------------------ evaluation
    @property
    def kind(self) -> int:
        return KIND_LINEAR if self.S is None else KIND_TABLE

    @property
    def n_nodes(self) -> int:
        return 0 if self.S is None else len(self.S)

    def make_state(self) -> Optional[FrictionState]:
        """A FrictionState with this model's sigma, v_s and beta (None if it needs none:
        a linear or a stateless model)."""
        if self.S is None or self.sigma == 0.0:
            return None
        return FrictionState(self.sigma, self.v_s, self.beta)

    def state_key(self) -> Optional[tuple]:
        """`FrictionState.key()` of the states this model needs (None: it needs none)."""
        if self.S is None or self.sigma == 0.0:
            return None
        return self.sigma, self.v_s, self.beta

    def force(self, x: float, xd: float, xdd: float, z=None) -> float:
        """Model force in N at position x (m), velocity xd (m/s), acceleration xdd (m/s^2).

        z: friction states (z1, z2) from a `FrictionState` driven by the same trajectory;
        None uses the stateless steady-motion approximation. Ignored by linear and
        stateless (sigma = 0) models.
        """
        if self.S is not None and (z is None or self.sigma == 0.0):
            z = steady_states(xd, self.v_s, self.beta)
        return self.force_z(x, xd, xdd, z)

    def force_z(self, x: float, xd: float, xdd: float, z) -> float:
        """Model force in N with the friction states z = (z1, z2) as given, also for a
        stateless model (tenth round of issue 12): its friction in the direction the states
        say, e.g. the anchor's, where `force` would take the direction of xd. The renderer's
        split of the model into the anchor's friction and its change (`anchoring`) needs
        it; with sigma > 0 it is `force(x, xd, xdd, z)`."""
        f = self.m * xdd + self.c * xd + self.k * x + self.offset
        S = self.S
        if S is None:
            return f
        u = (x - self.x0) / self.dx
        n1 = len(S) - 1
        if u <= 0.0:
            j, w = 0, 0.0
        elif u >= n1:
            j, w = n1 - 1, 1.0
        else:
            j = int(u)
            w = u - j
        w0 = 1.0 - w
        F, B, C = self.F, self.B, self.C
        z1, z2 = z
        return (f + w0 * S[j] + w * S[j + 1]
                + (w0 * F[j] + w * F[j + 1]) * z1 + (w0 * B[j] + w * B[j + 1]) * (z2 - z1)
                + (w0 * C[j] + w * C[j + 1]) * xd)

    def tables(self) -> Dict[str, list]:
        """{name: node values} of the tables ('S', 'F', 'B', 'C'; empty for linear models)."""
        if self.S is None:
            return {}
        return {'S': self.S, 'F': self.F, 'B': self.B, 'C': self.C}

    # ------------------------------------------------------------------ wire format
    def to_fields(self) -> Dict[str, float]:
        """Named float64 values (insertion order = wire order; BASE_FIELDS first)."""
        d = {'m': self.m, 'c': self.c, 'k': self.k, 'offset': self.offset,
             'valid': 1.0 if self.valid else 0.0, 'kind': float(self.kind)}
        if self.S is not None:
            d.update(x0=self.x0, dx=self.dx, sigma=self.sigma, v_s=self.v_s, beta=self.beta,
                     n=float(len(self.S)))
            for name, t in self.tables().items():
                for i, v in enumerate(t):
                    d[f'{name}{i}'] = float(v)
        if self.anchor is not None:
            d.update(zip(ANCHOR_FIELDS, self.anchor, strict=True))
        return d

    @classmethod
    def from_fields(cls, fields: Dict[str, float]) -> 'Impedance':
        """Inverse of `to_fields`. ValueError (naming the field) on missing or bad values."""
        if not isinstance(fields, dict):
            raise ValueError(f'fields must be a dict, got {type(fields).__name__}')
        for name in BASE_FIELDS:
            if name not in fields:
                raise ValueError(f'fields is missing {name!r}')
        kind = int(round(finite('kind', fields.get('kind', 0.0))))
        kw = {}
        if kind == KIND_TABLE:
            for name in ('x0', 'dx', 'sigma', 'v_s', 'beta', 'n'):
                if name not in fields:
                    raise ValueError(f'fields is missing {name!r} (table model)')
            n = int(round(finite('n', fields['n'])))
            if n < 2 or n > MAX_NODES:
                raise ValueError(f'n must be in 2..{MAX_NODES}, got {fields["n"]!r}')
            for name in 'SFBC':
                keys = [f'{name}{i}' for i in range(n)]
                missing = [k for k in keys if k not in fields]
                if missing:
                    raise ValueError(f'fields is missing {missing[0]!r} (table model)')
                kw[name] = [fields[k] for k in keys]
            kw.update(x0=fields['x0'], dx=fields['dx'], sigma=fields['sigma'],
                      v_s=fields['v_s'], beta=fields['beta'])
        elif kind != KIND_LINEAR:
            raise ValueError(f'kind must be 0 (linear) or 1 (table), got {fields["kind"]!r}')
        present = [n for n in ANCHOR_FIELDS if n in fields]
        if present:
            if len(present) != len(ANCHOR_FIELDS):
                missing = [n for n in ANCHOR_FIELDS if n not in fields]
                raise ValueError(f'fields is missing {missing[0]!r} (anchored model)')
            kw['anchor'] = [fields[n] for n in ANCHOR_FIELDS]
        valid = finite('valid', fields['valid']) > 0.5
        return cls(fields['m'], fields['c'], fields['k'], fields['offset'], valid, **kw)

    def copy(self, **changes) -> 'Impedance':
        kw = dict(m=self.m, c=self.c, k=self.k, offset=self.offset, valid=self.valid,
                  x0=self.x0, dx=self.dx, sigma=self.sigma, v_s=self.v_s, beta=self.beta,
                  S=self.S, F=self.F, B=self.B, C=self.C, status=self.status, anchor=self.anchor)
        kw.update(changes)
        return Impedance(**kw)

    def __repr__(self) -> str:
        base = (f'Impedance(m={self.m:.4g}, c={self.c:.4g}, k={self.k:.4g}, '
                f'offset={self.offset:.4g}, valid={self.valid}')
        if self.S is not None:
            base += f', table n={len(self.S)} x0={self.x0:.4g} dx={self.dx:.4g}'
        return base + (f', status={self.status!r})' if self.status else ')')


def check_state(x, xd, xdd) -> tuple:
    """Validate a trajectory sample; returns floats (ValueError naming x, xd or xdd)."""
    return finite('x', x), finite('xd', xd), finite('xdd', xdd)


__all__ = ['Impedance', 'Anchor', 'FrictionState', 'steady_states', 'BASE_FIELDS', 'ANCHOR_FIELDS',
           'KIND_LINEAR', 'KIND_TABLE', 'check_state']
