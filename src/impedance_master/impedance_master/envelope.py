"""The envelope of physically plausible environment models (issue 10): what a catheter in a
vessel can be, generously, and nothing else.

An `Impedance` is accepted only if its parameters are finite and within bounds AND the force
it predicts anywhere in the workspace (inserted length, speed and acceleration the slave's
insertion axis can reach, any friction state) stays below ``max_force``. The identifiers
check it before publishing and after loading a state file; the master's renderer checks it
before rendering, so a model that passes the wire format but not physics (m = 1e308,
k = 1e300, a tampered state file giving 72 kN) never reaches the hand.

The bounds are 5-10x beyond anything the project's vessels produce (their forces stay below
0.6 N, clinical insertion forces below 2 N; catheter masses are grams; drag below
2 N s/m): the envelope refuses absurd models, it does not judge good from bad ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from catheter_common.checks import check_fields, finite
from impedance_master.impedance import Impedance


@dataclass(frozen=True)
class ModelEnvelope:
    """Bounds of an acceptable model (SI units).

    Attributes:
        max_mass: kg, |m| (default 1: a catheter weighs grams).
        max_damping: N s/m, |c| and |c + C(x)| on the grid (default 200).
        max_stiffness: N/m, |k| (default 2000).
        max_offset: N, |offset| (default 10).
        max_table: N, |S|, |F|, |B|, |D| node values (default 10).
        max_force: N, largest |force| the model may predict anywhere in the workspace
            (default 10: five times the clinical 2 N insertion range).
        x_lo, x_hi: m, workspace of inserted lengths (default -0.02..0.2, the insertion
            axis's stroke); max_speed m/s (0.1), max_accel m/s^2 (2): the axis's limits.
        max_sigma: m, the presliding length sigma must be in [0, max_sigma]
            (default 0.05; 0: a stateless friction law, `Impedance` sigma); max_v_s: m/s
            (1); max_beta: (10).
        max_anchor_force: N, |anchor f| and |anchor r| (default 20).
    `check(imp)` returns None (accepted) or the reason; `force_bound(imp)` the largest |f|
    over the workspace (exact for the model's piecewise-linear structure, with the friction
    states over their whole ranges: |z1| <= 1, |z2 - z1| <= 2 + beta).
    """

    max_mass: float = 1.0
    max_damping: float = 200.0
    max_stiffness: float = 2000.0
    max_offset: float = 10.0
    max_table: float = 10.0
    max_force: float = 10.0
    x_lo: float = -0.02
    x_hi: float = 0.2
    max_speed: float = 0.1
    max_accel: float = 2.0
    max_sigma: float = 0.05
    max_v_s: float = 1.0
    max_beta: float = 10.0
    max_anchor_force: float = 20.0

    def __post_init__(self):
        check_fields(self, positive=('max_mass', 'max_damping', 'max_stiffness', 'max_offset',
                                     'max_table', 'max_force', 'max_speed', 'max_accel',
                                     'max_sigma', 'max_v_s', 'max_beta', 'max_anchor_force'))
        if not finite('x_lo', self.x_lo) < finite('x_hi', self.x_hi):
            raise ValueError(f'x_lo must be < x_hi, got {self.x_lo!r}, {self.x_hi!r}')

    def check(self, imp: Impedance) -> Optional[str]:
        """None if `imp` is inside the envelope, else a short reason naming the quantity."""
        if not isinstance(imp, Impedance):
            return f'not an Impedance ({type(imp).__name__})'
        for name, bound in (('m', self.max_mass), ('c', self.max_damping),
                            ('k', self.max_stiffness), ('offset', self.max_offset)):
            v = getattr(imp, name)
            if not abs(v) <= bound:
                return f'|{name}| = {abs(v):.3g} above {bound:g}'
        if imp.S is not None:
            if not 0.0 <= imp.sigma <= self.max_sigma:
                return f'sigma = {imp.sigma:.3g} m outside [0, {self.max_sigma:g}]'
            if not imp.v_s <= self.max_v_s:
                return f'v_s = {imp.v_s:.3g} m/s above {self.max_v_s:g}'
            if not imp.beta <= self.max_beta:
                return f'beta = {imp.beta:.3g} above {self.max_beta:g}'
            if not abs(imp.x0) <= 1.0 or not imp.dx <= 1.0:
                return f'grid x0 = {imp.x0:.3g} m, dx = {imp.dx:.3g} m outside 1 m'
            for name, t in imp.tables().items():
                bound = self.max_damping if name == 'C' else self.max_table
                worst = max(abs(v) for v in t)
                if not worst <= bound:
                    return f'|{name}| = {worst:.3g} above {bound:g}'
            for v in imp.C:
                if not abs(imp.c + v) <= self.max_damping:
                    return f'|c + C| = {abs(imp.c + v):.3g} above {self.max_damping:g}'
        a = imp.anchor
        if a is not None:
            if not (abs(a.f) <= self.max_anchor_force and abs(a.r) <= self.max_anchor_force):
                return f'anchor force {a.f:.3g} / residual {a.r:.3g} N above ' \
                       f'{self.max_anchor_force:g}'
            if not (self.x_lo - 1.0 <= a.x <= self.x_hi + 1.0 and abs(a.xd) <= 10.0
                    and abs(a.xdd) <= 1e3 and max(abs(a.z1), abs(a.z2)) <= 20.0):
                return 'anchor state outside the workspace'
        bound = self.force_bound(imp)
        if not bound <= self.max_force:
            return f'predicted force up to {bound:.3g} N above {self.max_force:g}'
        return None

    def accepts(self, imp: Impedance) -> bool:
        return self.check(imp) is None

    def force_bound(self, imp: Impedance) -> float:
        """Largest |force| (N) `imp` predicts over the workspace (see class doc); inf if it
        overflows. The bound is a sum of terms each piecewise linear in x, so its maximum
        over x is at a grid node or at an end of the workspace."""
        with np.errstate(all='ignore'):
            xs = [self.x_lo, self.x_hi]
            if imp.S is None:
                x = np.asarray(xs)
                static = imp.k * x + imp.offset
                damping = np.full(2, imp.c)
                fric = 0.0
            else:
                n = len(imp.S)
                nodes = imp.x0 + imp.dx * np.arange(n)
                if nodes[0] > self.x_lo and nodes[-1] < self.x_hi:     # dx > 0 (Impedance)
                    return self._table_bound(imp, nodes.tolist())
                x = np.concatenate([xs, nodes[(nodes > self.x_lo) & (nodes < self.x_hi)]])
                grid = lambda t: np.interp(x, nodes, np.asarray(t, dtype=float))  # noqa: E731
                static = imp.k * x + imp.offset + grid(imp.S)
                damping = imp.c + grid(imp.C)
                fric = np.abs(grid(imp.F)) + (2.0 + imp.beta) * np.abs(grid(imp.B))
            total = (np.abs(static) + np.abs(damping) * self.max_speed + fric).max() \
                + abs(imp.m) * self.max_accel
        out = float(total)
        return out if math.isfinite(out) else math.inf

    def _table_bound(self, imp: Impedance, nodes: list) -> float:
        """`force_bound` of a table model whose whole grid lies inside the workspace (every
        model of the default identifier): the tables at the workspace's ends are their edge
        values, so the maximum is over the nodes and the two ends. Python floats over 17
        nodes: a third of the numpy path's time, the same value (inf on overflow)."""
        k, off, c, vmax = imp.k, imp.offset, imp.c, self.max_speed
        b2 = 2.0 + imp.beta
        S, C, F, B = imp.S, imp.C, imp.F, imp.B
        vals = [abs(k * x + off + s) + abs(c + d) * vmax + (abs(f) + b2 * abs(b))
                for x, s, d, f, b in zip(nodes, S, C, F, B, strict=True)]
        for x, i in ((self.x_lo, 0), (self.x_hi, -1)):
            vals.append(abs(k * x + off + S[i]) + abs(c + C[i]) * vmax
                        + (abs(F[i]) + b2 * abs(B[i])))
        # every term is >= 0 and the inputs are finite (`Impedance` checks them): an
        # overflow is +inf, never NaN
        return max(vals) + abs(imp.m) * self.max_accel


#: the envelope every identifier and renderer uses unless given another
DEFAULT_ENVELOPE = ModelEnvelope()
