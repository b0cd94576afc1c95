"""Data types of the public API: Catheter, Loads, Shape, BatchShape (no rclpy, SI units).

Frame: ``catheter_base`` -- origin at the clamp, x along the undeformed catheter, y in the
bending plane. Angles in rad, counter-clockwise from +x. Arc-length fractions s in [0, 1].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Optional, Tuple

import numpy as np
from numpy.typing import ArrayLike

from catheter_common.checks import finite

from .arcs import g_only, rate_funcs, rate_offset
from .status import Status, status_codes, status_of, warning_text


SPACINGS = ('uniform', 'graded')
_FRAC_CACHE = {}


def uniform_fractions(n: int) -> np.ndarray:
    """Arc lengths of n equal arcs as fractions of the catheter length, (n,) (read-only, cached)."""
    f = _FRAC_CACHE.get(n)
    if f is None:
        f = np.full(n, 1.0 / n)
        f.setflags(write=False)
        _FRAC_CACHE[n] = f
    return f


def _check_fractions(fractions, shape):
    f = np.asarray(fractions, dtype=float)
    if f.shape != shape or not np.min(f) > 0 or not np.isfinite(np.sum(f)):
        raise ValueError(f'fractions must be positive, finite, of shape {shape}')
    return f


def _vec2(value, name: str) -> Tuple[float, float]:
    a = np.asarray(value, dtype=float) if not isinstance(value, str) else None
    if a is None or a.shape != (2,):
        raise ValueError(f'{name} must be a pair (fx, fy), got {value!r}')
    if not np.all(np.isfinite(a)):
        raise ValueError(f'{name} must be finite, got {value!r}')
    return float(a[0]), float(a[1])


@dataclass(frozen=True)
class Catheter:
    """A planar, initially straight, clamped catheter.

    length: m (> 0). ei: flexural rigidity E*I in N m^2 (> 0).
    """
    length: float
    ei: float

    def __post_init__(self):
        length = finite('length', self.length)
        ei = finite('ei', self.ei)
        if length <= 0:
            raise ValueError(f'length must be positive (m), got {length}')
        if ei <= 0:
            raise ValueError(f'ei must be positive (N m^2), got {ei}')
        object.__setattr__(self, 'length', length)
        object.__setattr__(self, 'ei', ei)


@dataclass(frozen=True)
class Loads:
    """External loads, in the catheter_base frame unless ``follower``.

    tip_force: (fx, fy) N. With ``follower=True`` the components are in the TIP frame
        (x along the tip tangent, y its normal), so the force turns with the tip (tendon pull).
    tip_moment: mz, N m (counter-clockwise positive).
    point_forces: sequence of (s, fx, fy): s the arc-length fraction in (0, 1], force in N,
        fixed in the base frame. A point force at s = 1 adds to the tip force (base frame).
    """
    tip_force: Tuple[float, float] = (0.0, 0.0)
    tip_moment: float = 0.0
    follower: bool = False
    point_forces: Tuple[Tuple[float, float, float], ...] = field(default_factory=tuple)

    def __post_init__(self):
        object.__setattr__(self, 'tip_force', _vec2(self.tip_force, 'tip_force'))
        object.__setattr__(self, 'tip_moment', finite('tip_moment', self.tip_moment))
        if not isinstance(self.follower, (bool, np.bool_)):
            raise ValueError(f'follower must be a bool, got {self.follower!r}')
        object.__setattr__(self, 'follower', bool(self.follower))
        pf = self.point_forces
        if pf is None:
            pf = ()
        try:
            rows = [tuple(r) for r in pf]
        except TypeError:
            raise ValueError(f'point_forces must be a sequence of (s, fx, fy), '
                             f'got {pf!r}') from None
        out = []
        for r in rows:
            if len(r) != 3:
                raise ValueError(f'point_forces entries must be (s, fx, fy), got {r!r}')
            s = finite('point_forces s', r[0])
            if not 0.0 < s <= 1.0:
                raise ValueError(f'point_forces s must be in (0, 1], got {s}')
            out.append((s, finite('point_forces fx', r[1]),
                        finite('point_forces fy', r[2])))
        object.__setattr__(self, 'point_forces', tuple(out))

    def load_parameter(self, cat: Catheter) -> float:
        """Dimensionless size of the loading: (sum |F|) L^2/EI + |M| L/EI."""
        f = math.hypot(*self.tip_force) + sum(math.hypot(fx, fy) for _, fx, fy in self.point_forces)
        return f * cat.length ** 2 / cat.ei + abs(self.tip_moment) * cat.length / cat.ei


class Shape:
    """A solved planar centreline (FAM or the reference rod), base at (0, 0) heading +x.

    Attributes
    ----------
    tip : ndarray (2,), m.          tip_angle : float, rad (tangent angle at the tip).
    arc_angles : ndarray (n_arcs,), rad -- the bending angle phi_i of each arc, base -> tip
        (arc i has length arc_lengths[i]: equal arcs, or graded, see fam.graded_fractions)
        (for the reference rod: tangent-angle increments over 100 equal pieces).
    converged : bool.  iterations : int (Newton iterations, all continuation steps).
    stable : bool -- False when the returned equilibrium is known to be unstable (a straight
        catheter under an axial compression past its buckling load: loading from zero keeps
        the straight equilibrium; it is returned and flagged, see ``warning``).
    warning : str -- '' or a short reason (non-convergence, snap-through, instability).
    snap_through : bool -- the loading path from zero has a fold; the equilibrium found
        beyond it was returned.
    status : Status (IntEnum, 0 = CONVERGED, see ``status.Status``; ``status.message``),
        derived from converged, stable and snap_through.
    residual : float -- max |residual| of the solved equations (rad for FAM, N m for the rod).
    arc_model : str -- 'clothoid', 'exact', 'bezier' or 'elastica'.
    arc_rates : ndarray (n_arcs,) or None -- clothoid arcs only: rho_i = kappa1_i l_i^2, the
        curvature change along arc i times its length squared (see ``arcs``).
    spacing : str -- 'uniform' or 'graded' arc lengths.  arc_lengths : ndarray (n_arcs,), m.
    """

    def __init__(self, length: float, tip, tip_angle: float, arc_angles, converged: bool,
                 iterations: int, points_fn: Callable[[np.ndarray], np.ndarray],
                 angles_fn: Callable[[np.ndarray], np.ndarray], stable: bool = True,
                 warning: str = '', residual: float = 0.0, arc_model: str = 'exact',
                 snap_through: bool = False):
        self.length = float(length)
        self.snap_through = bool(snap_through)
        self.tip = np.asarray(tip, dtype=float).reshape(2)
        self.tip_angle = float(tip_angle)
        self.arc_angles = np.asarray(arc_angles, dtype=float)
        self.converged = bool(converged)
        self.iterations = int(iterations)
        self.stable = bool(stable)
        self.warning = str(warning)
        self.residual = float(residual)
        self.arc_model = arc_model
        self._points_fn = points_fn
        self._angles_fn = angles_fn
        self.spacing = 'uniform'
        self._arc_lengths = None
        self.arc_rates = None

    @property
    def status(self) -> Status:
        """Outcome code (see ``status.Status``), from converged, stable and snap_through."""
        return status_of(self.converged, self.stable, self.snap_through)

    @property
    def arc_lengths(self) -> np.ndarray:
        """Arc lengths (n_arcs,) in m (equal unless spacing='graded')."""
        if self._arc_lengths is None:
            n = self.arc_angles.size
            self._arc_lengths = np.full(n, self.length / n) if n else np.zeros(0)
        return self._arc_lengths

    def points_at(self, s: ArrayLike) -> np.ndarray:
        """Positions (len(s), 2) in m at arc-length fractions s in [0, 1]."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if s.ndim != 1 or not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s > 1):
            raise ValueError('s must be a 1-D array of fractions in [0, 1]')
        return self._points_fn(s)

    def angles_at(self, s: ArrayLike) -> np.ndarray:
        """Tangent angles (len(s),) in rad at arc-length fractions s in [0, 1]."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if s.ndim != 1 or not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s > 1):
            raise ValueError('s must be a 1-D array of fractions in [0, 1]')
        return self._angles_fn(s)

    def centerline(self, k: int = 50) -> np.ndarray:
        """(k, 2) positions in m, base -> tip, at equal arc-length spacing (k >= 2)."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2:
            raise ValueError(f'k must be an integer >= 2, got {k!r}')
        return self.points_at(np.linspace(0.0, 1.0, int(k)))

    def __repr__(self):
        return (f'Shape(tip={self.tip.tolist()}, tip_angle={self.tip_angle:.6g}, '
                f'n_arcs={self.arc_angles.size}, converged={self.converged}, '
                f'iterations={self.iterations}, stable={self.stable}, status={self.status.name}, '
                f'model={self.arc_model!r})')


def _locate(bounds, s):
    """Arc index (int array) and fraction inside it for arc-length fractions s; bounds (N+1,)."""
    n = bounds.size - 1
    i = np.clip(np.searchsorted(bounds, s, side='right') - 1, 0, n - 1)
    return i, (s - bounds[i]) / (bounds[i + 1] - bounds[i])


def _bounds(frac):
    b = np.concatenate([[0.0], np.cumsum(frac)])
    b[-1] = 1.0
    return b


def arc_shape(length: float, phi: ArrayLike, tip: Optional[complex] = None,
              tip_angle: Optional[float] = None, fractions: Optional[ArrayLike] = None,
              spacing: str = 'uniform', rates: Optional[ArrayLike] = None, **kw) -> Shape:
    """Shape of N circular arcs with bending angles ``phi`` (N,), base at the origin; arc
    lengths ``length * fractions`` ((N,), summing to 1; None: equal arcs). ``rates`` (N,):
    clothoid arcs with rho_i = kappa1_i l_i^2 (first order in rho, see ``arcs``).

    ``tip`` (complex) and ``tip_angle`` may be passed when already known; the arc geometry
    for ``points_at`` is built lazily on first use."""
    phi = np.asarray(phi, dtype=float)
    n = phi.size
    trusted = kw.pop('_trusted', False)      # internal callers pass checked fractions
    if not n:
        frac = np.zeros(0)
    elif fractions is None:
        frac = uniform_fractions(n)
    else:
        frac = fractions if trusted else _check_fractions(fractions, (n,))
    l = length * frac
    cache = {}

    def geometry():
        if not cache:
            th_end = np.cumsum(phi)
            th_start = th_end - phi
            E = np.exp(1j * th_start)
            d = l * E * g_only(phi)
            if rates is not None:
                d = d + l * E * 1j * rates * rate_funcs(phi)[0]
            P_end = np.cumsum(d)
            bounds = _bounds(frac) if n else np.array([0.0, 1.0])
            if not np.any(phi):
                # exactly straight: no accumulated round-off, tip == (L, 0)
                P_end = length * bounds[1:] + 0j
                P_end[-1] = length
            cache.update(th_start=th_start, E=E, P_end=P_end, bounds=bounds,
                         P_start=np.concatenate([[0j], P_end[:-1]]))
        return cache

    def locate(s):
        return _locate(geometry()['bounds'], s)

    def points(s):
        c = geometry()
        i, tau = locate(s)
        u = tau * g_only(phi[i] * tau)
        if rates is not None:
            u = u + 1j * rates[i] * rate_offset(phi[i], tau)
        z = c['P_start'][i] + l[i] * c['E'][i] * u
        z = np.where(s >= 1.0, c['P_end'][-1], z)
        return np.stack([z.real, z.imag], axis=-1)

    def angles(s):
        c = geometry()
        i, tau = locate(s)
        th = c['th_start'][i] + phi[i] * tau
        if rates is not None:
            th = th + rates[i] * 0.5 * (tau * tau - tau)
        return th

    if tip is None or not np.any(phi):
        tip = geometry()['P_end'][-1]
    if tip_angle is None:
        tip_angle = float(np.sum(phi)) if n else 0.0
    sh = Shape(length, (tip.real, tip.imag), tip_angle, phi,
               points_fn=points, angles_fn=angles, **kw)
    sh.spacing = spacing
    sh._arc_lengths = l
    if rates is not None:
        rates = np.asarray(rates, dtype=float)
        sh.arc_rates = rates
    return sh


class BatchShape:
    """Results of ``solve_fam_batch``: B load cases with N arcs each.

    arc_angles (B, N) rad; arc_lengths (B, N) m; tips (B, 2) m; tip_angles (B,) rad;
    converged (B,) bool; stable (B,) bool; snap_through (B,) bool; status (B,) int (codes of
    ``status.Status``, derived from the three flags); iterations (B,) int; residual (B,) rad;
    spacing 'uniform' or 'graded' (fractions (B, N) of L per case, None: equal arcs).
    """

    def __init__(self, length: float, arc_angles, converged, iterations, stable, residual,
                 arc_model: str, spacing='uniform', fractions=None, rates=None,
                 snap_through=None):
        self.length = float(length)
        #: clothoid rates (B, N) (rho = kappa1 l^2 per arc) or None for circular arcs
        self.arc_rates = None if rates is None else np.asarray(rates, dtype=float)
        self.arc_angles = np.asarray(arc_angles, dtype=float)
        self.converged = np.asarray(converged, dtype=bool)
        self.iterations = np.asarray(iterations, dtype=int)
        self.stable = np.asarray(stable, dtype=bool)
        self.residual = np.asarray(residual, dtype=float)
        self.arc_model = arc_model
        self.spacing = spacing
        B, n = self.arc_angles.shape
        self.snap_through = (np.zeros(B, dtype=bool) if snap_through is None
                             else np.asarray(snap_through, dtype=bool))
        if fractions is None:
            frac = np.broadcast_to(uniform_fractions(n) if n else np.zeros(0), (B, n))
        else:
            frac = _check_fractions(fractions, (B, n))
        self._frac = frac
        self._bounds = np.concatenate([np.zeros((B, 1)), np.cumsum(frac, axis=1)], axis=1)
        self._bounds[:, -1] = 1.0
        self._l = self.length * frac
        #: arc lengths (B, N) m (per case: graded arcs follow each case's curvature)
        self.arc_lengths = self._l
        th_end = np.cumsum(self.arc_angles, axis=1)
        self.tip_angles = th_end[:, -1].copy() if n else np.zeros(B)
        d = self._chords(self.arc_angles, np.exp(1j * (th_end - self.arc_angles)))
        tip = d.sum(axis=1)
        straight = ~np.any(self.arc_angles != 0.0, axis=1)
        tip = np.where(straight, self.length + 0j, tip)
        self.tips = np.stack([tip.real, tip.imag], axis=-1)

    def _chords(self, phi, E):
        d = self._l * E * g_only(phi)
        if self.arc_rates is not None:
            d = d + self._l * E * 1j * self.arc_rates * rate_funcs(phi)[0]
        return d

    def __len__(self):
        return self.arc_angles.shape[0]

    @property
    def status(self) -> np.ndarray:
        """Outcome codes (B,) int (``status.Status`` values) from converged, stable and
        snap_through."""
        return status_codes(self.converged, self.stable, self.snap_through)

    def shape(self, b: int) -> Shape:
        """The b-th case as a Shape."""
        conv, stable = bool(self.converged[b]), bool(self.stable[b])
        snap = bool(self.snap_through[b])
        return arc_shape(self.length, self.arc_angles[b], converged=conv,
                         iterations=int(self.iterations[b]), stable=stable, snap_through=snap,
                         warning=warning_text(conv, stable, snap, float(self.residual[b])),
                         residual=float(self.residual[b]), arc_model=self.arc_model,
                         spacing=self.spacing, fractions=self._frac[b],
                         rates=None if self.arc_rates is None else self.arc_rates[b])

    def points_at(self, s: ArrayLike) -> np.ndarray:
        """(B, len(s), 2) positions in m at arc-length fractions s in [0, 1]."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        if s.ndim != 1 or not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s > 1):
            raise ValueError('s must be a 1-D array of fractions in [0, 1]')
        phi = self.arc_angles
        B, n = phi.shape
        th_end = np.cumsum(phi, axis=1)
        th_start = th_end - phi
        E = np.exp(1j * th_start)
        d = self._chords(phi, E)
        P_end = np.cumsum(d, axis=1)
        P_start = P_end - d
        bnd = self._bounds
        if n:
            i = np.clip(np.sum(bnd[:, None, 1:-1] <= s[None, :, None], axis=2), 0, n - 1)  # (B, k)
        else:
            i = np.zeros((B, s.size), dtype=int)
        rows = np.arange(B)[:, None]
        lo, hi = bnd[rows, i], bnd[rows, i + 1]
        tau = (s[None, :] - lo) / (hi - lo)
        ph = phi[rows, i]
        u = tau * g_only(ph * tau)
        if self.arc_rates is not None:
            u = u + 1j * self.arc_rates[rows, i] * rate_offset(ph, tau)
        z = P_start[rows, i] + self._l[rows, i] * E[rows, i] * u
        z = np.where(s[None, :] >= 1.0, P_end[:, -1:], z)
        straight = ~np.any(phi != 0.0, axis=1)
        z = np.where(straight[:, None], self.length * s[None, :] + 0j, z)
        return np.stack([z.real, z.imag], axis=-1)

    def centerlines(self, k: int = 50) -> np.ndarray:
        """(B, k, 2) positions in m, base -> tip, at equal arc-length spacing."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 2:
            raise ValueError(f'k must be an integer >= 2, got {k!r}')
        return self.points_at(np.linspace(0.0, 1.0, int(k)))
