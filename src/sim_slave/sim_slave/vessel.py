"""Insertion force of a catheter in a vascular phantom (the simulated environment of the slave).

Deliberately *not* the linear ``f = m x'' + c x' + k x`` model the thesis's identifier
assumes (Eq. 29): the force is the sum of

* **friction** along the inserted length, LuGre type (Canudas de Wit et al. 1995): a bristle
  state ``z`` gives pre-sliding stick (elastic response to displacements smaller than
  ``presliding_displacement``), a Stribeck breakaway peak when motion starts and a Coulomb
  level while sliding; the friction levels grow with the inserted length (a longer wetted
  length and more wrap in the curved vessel: a capstan-like quadratic term); retraction
  gives friction of the opposite sign;
* **viscous drag** proportional to inserted length and velocity (blood/glycerol film);
* **wall contact**, Hunt-Crossley ``k d^n (1 + a d')`` once the tip passes ``wall_depth``
  (nonlinear, dissipative, never pulls);
* a **cardiac disturbance**, a ``cardiac_frequency`` sinusoid (72 beats/min) whose amplitude
  grows with inserted length up to ``cardiac_depth``;
* optionally (``shaft_stiffness > 0``) an axially compliant shaft between the robot's drive
  and the inserted part (a mass): with the Stribeck breakaway this gives genuine stick-slip
  (a sawtooth force at slow insertion). Off by default (rigid shaft, kinematic drive);
* optionally (``extras``, `sim_slave.vessel_extras.VesselExtras`, all off by default) terms
  of other structure: friction growing quadratically or in steps, smooth (stateless)
  Coulomb friction, a Kelvin-Voigt wall, a stenosis, breathing. The named vessels of the
  family are in `sim_slave.vessels`.

Sign convention: the returned force is the axial force the vessel exerts against the
catheter, as the slave's force sensor reads it: positive resists insertion (x increasing),
negative resists retraction. ``x <= 0`` (catheter not inserted) gives zero force.

Pure Python (no rclpy, no numpy in the hot path): about a microsecond per call.
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import NamedTuple, Optional

from catheter_common.checks import CheckedFields, checked, finite, seed as check_seed
from sim_slave.vessel_extras import (VesselExtras, extra_friction, smooth_coulomb,
                                     stenosis_force)


@dataclass(frozen=True)
class VesselParams(CheckedFields):
    """Parameters of the vessel interaction (SI units). Defaults reproduce the thesis's range.

    The thesis (Ch. 4, Exp. I) reports a maximum insertion force of 0.387 N for insertion up to
    56 mm at up to 41.3 mm/s in a SAM Plus phantom with a Runway guide catheter. The defaults
    split that budget at x = 56 mm, v = 41.3 mm/s into Coulomb friction 0.262 N, viscous drag
    0.046 N, wall contact 0.088 N (about 0.40 N in total) plus a 0.01 N cardiac ripple.

    Attributes:
        friction_per_length: N/m, 3.0. Coulomb friction per inserted metre at small depth
            (``Fc(x) = friction_per_length * x * (1 + x / capstan_length)``). Chosen so that
            Fc(56 mm) = 0.262 N, i.e. friction is about 2/3 of the thesis's 0.387 N maximum,
            as typical for catheter insertion in phantoms (friction dominates insertion force).
        capstan_length: m, 0.10. Length over which friction per metre doubles: more of the
            catheter wraps around the vessel's bends as it goes deeper (capstan effect,
            F ~ exp(mu theta), linearised). Makes friction super-linear in depth. Must be > 0;
            use a large value for purely linear growth.
        stribeck_ratio: -, 1.4. Breakaway (static) over Coulomb friction, Fs/Fc >= 1.
            Polymer on wet silicone: static/kinetic friction ratios of 1.2-1.6 are usual.
        stribeck_velocity: m/s, 0.002. Velocity scale of the Stribeck decay from Fs to Fc
            (LuGre ``v_s``); a few mm/s, well below the 41.3 mm/s maximum insertion speed.
        presliding_displacement: m, 3e-4. Bristle deflection at the Coulomb level
            (``z_c = Fc / sigma0`` of LuGre): displacements smaller than this stick
            (elastic response, no sliding). 0.3 mm stands for the axial compliance of the
            catheter shaft in its introducer sheath.
        bristle_damping: s/m, 0.5. Normalised LuGre micro-damping: friction adds
            ``Fc(x) * bristle_damping * dz/dt`` during pre-sliding (dz/dt <= |v|).
        viscous_per_length: N s/m^2, 20.0. Viscous drag per inserted metre:
            ``c(x) = viscous_per_length * x``; gives 0.046 N at 56 mm and 41.3 mm/s.
        wall_depth: m, 0.045. Inserted length at which the tip meets the vessel wall (a bend);
            below it the wall force is exactly zero. Chosen inside the thesis's 0-56 mm stroke
            so that Experiment-I-like motions visit the contact.
        wall_stiffness: N/m^n, 70.0. Hunt-Crossley stiffness ``k``: 0.081 N at 11 mm past
            the wall (n = 1.5), the order of the soft-tissue contact forces of 0.1-0.3 N
            in DESIGN section 1.
        wall_exponent: -, 1.5. Hunt-Crossley exponent ``n`` (Hertzian contact: 1.5).
        wall_damping: s/m, 2.0. Hunt-Crossley damping ``a`` in ``k d^n (1 + a d')``: +8 % at
            41.3 mm/s. The contact force is clipped at zero (the wall never pulls).
        cardiac_amplitude: N, 0.01. Amplitude of the cardiac disturbance (same order as the
            sensor noise; small next to the 0.4 N insertion force).
        cardiac_frequency: Hz, 1.2. Heart rate of 72 beats per minute.
        cardiac_depth: m, 0.03. Inserted length at which the cardiac disturbance reaches full
            amplitude (linear ramp from zero at x = 0: a catheter outside the body feels none).
        shaft_stiffness: N/m, 0.0 = rigid (default). Opt-in axial compliance of the catheter
            shaft between the robot's drive and the inserted part: with it the inserted part
            is a mass on a spring-damper and genuine stick-slip (sawtooth force at slow
            insertion) appears. A 7 Fr polymer shaft (E ~ 50 MPa, A = 1.9 mm^2) over ~1 m
            gives EA/L ~ 90 N/m; slack in the introducer lowers it: 50 N/m is a fair value.
        shaft_damping: N s/m, 0.5. Damping of the shaft spring (only with a compliant shaft).
        catheter_mass: kg, 0.005. Moving mass of the catheter (only with a compliant shaft;
            a 1 m 7 Fr catheter weighs a few grams).
    """

    friction_per_length: float = checked(3.0, 'nonneg')
    capstan_length: float = checked(0.10, 'positive')
    stribeck_ratio: float = checked(1.4)
    stribeck_velocity: float = checked(0.002, 'positive')
    presliding_displacement: float = checked(3e-4, 'positive')
    bristle_damping: float = checked(0.5, 'nonneg')
    viscous_per_length: float = checked(20.0, 'nonneg')
    wall_depth: float = checked(0.045, 'nonneg')
    wall_stiffness: float = checked(70.0, 'nonneg')
    wall_exponent: float = checked(1.5, 'positive')
    wall_damping: float = checked(2.0, 'nonneg')
    cardiac_amplitude: float = checked(0.01, 'nonneg')
    cardiac_frequency: float = checked(1.2, 'nonneg')
    cardiac_depth: float = checked(0.03, 'positive')
    shaft_stiffness: float = checked(0.0, 'nonneg')
    shaft_damping: float = checked(0.5, 'nonneg')
    catheter_mass: float = checked(0.005, 'positive')

    def __post_init__(self):
        super().__post_init__()
        if self.stribeck_ratio < 1.0:
            raise ValueError(f'stribeck_ratio must be >= 1, got {self.stribeck_ratio!r}')


class VesselForce(NamedTuple):
    """The components of one force evaluation, N (total = sum of the four): friction
    (LuGre or smooth Coulomb), viscous drag, wall (the tip's contacts: wall and stenosis),
    cardiac (the physiological disturbances: cardiac and breathing)."""
    friction: float
    viscous: float
    wall: float
    cardiac: float
    total: float


class VesselModel:
    """Stateful vessel interaction force (LuGre friction state, time of the last call).

    Call :meth:`force` once per control step with non-decreasing ``t``.

    Args:
        params: a :class:`VesselParams` (defaults if None).
        seed: int >= 0 or None; sets the phases of the cardiac and breathing disturbances
            (deterministic for a seed; None draws random phases).
        extras: a `VesselExtras` (structure terms beyond the phantom's; None: none).
    """

    def __init__(self, params: Optional[VesselParams] = None, seed: Optional[int] = 0,
                 extras: Optional[VesselExtras] = None):
        if params is None:
            params = VesselParams()
        if not isinstance(params, VesselParams):
            raise ValueError(f'params must be a VesselParams, got {type(params).__name__}')
        if extras is not None and not isinstance(extras, VesselExtras):
            raise ValueError(f'extras must be a VesselExtras, got {type(extras).__name__}')
        self.params = params
        self.extras = extras if extras is not None else VesselExtras()
        e = self.extras
        self._extra_friction = e.friction_terms
        self._smooth = e.coulomb_velocity > 0.0
        self._stenosis = e.stenosis_force > 0.0 and e.stenosis_depth > 0.0
        self._breathing = e.breathing_amplitude > 0.0
        self.seed = check_seed('seed', seed)
        rng = random.Random(seed)
        self.cardiac_phase = rng.uniform(0.0, 2.0 * math.pi)
        self.breathing_phase = rng.uniform(0.0, 2.0 * math.pi)
        self.reset()

    def reset(self) -> None:
        """Forget the friction state and the time of the last call (catheter at rest, unloaded)."""
        self.z = 0.0                  # m, LuGre bristle deflection
        self.y: Optional[float] = None   # m, inserted length of the catheter's inserted part
        self.yd = 0.0                 # m/s (equal to the drive's x, xd with a rigid shaft)
        self._x_last = 0.0
        self._t_last: Optional[float] = None
        self.last = VesselForce(0.0, 0.0, 0.0, 0.0, 0.0)

    # -- depth-dependent levels (also useful to tests and to documentation) --
    def coulomb_force(self, x: float) -> float:
        """Coulomb (sliding) friction level Fc(x) in N at inserted length x [m] (0 for x <= 0)."""
        p = self.params
        xin = x if x > 0.0 else 0.0
        fc = p.friction_per_length * xin * (1.0 + xin / p.capstan_length)
        if self._extra_friction:
            fc += extra_friction(self.extras, xin)
        return fc

    def breakaway_force(self, x: float) -> float:
        """Static (breakaway) friction level Fs(x) = stribeck_ratio * Fc(x), N."""
        return self.params.stribeck_ratio * self.coulomb_force(x)

    def steady_force(self, x: float, xd: float) -> float:
        """Noise- and disturbance-free force in N for steady sliding at x [m], xd [m/s]
        (friction state at equilibrium; no cardiac term). An exact reference for tests."""
        p = self.params
        x = finite('x', x)
        xd = finite('xd', xd)
        fc = self.coulomb_force(x)
        if xd != 0.0:
            g = 1.0 + (p.stribeck_ratio - 1.0) * math.exp(-(xd / p.stribeck_velocity) ** 2)
            fr = (smooth_coulomb(self.extras, fc, g, xd) if self._smooth
                  else math.copysign(fc * g, xd))
        else:
            fr = 0.0
        xin = x if x > 0.0 else 0.0
        f = fr + p.viscous_per_length * xin * xd + self._wall(x, xd)
        return f + stenosis_force(self.extras, x) if self._stenosis else f

    def wall_force(self, x: float, xd: float) -> float:
        """Hunt-Crossley wall contact force in N at x [m], xd [m/s] (stateless; 0 before the
        wall, never negative). The tip load the camera simulation bends the catheter with."""
        return self._wall(finite('x', x), finite('xd', xd))

    def _wall(self, x: float, xd: float) -> float:
        p = self.params
        d = x - p.wall_depth
        if d <= 0.0 or p.wall_stiffness == 0.0:
            return 0.0
        w = p.wall_stiffness * d ** p.wall_exponent * (1.0 + p.wall_damping * xd) \
            + self.extras.wall_viscous * xd
        return w if w > 0.0 else 0.0

    def force(self, t: float, x: float, xd: float) -> float:
        """True (noise-free) insertion force in N.

        Args:
            t: time in s, non-decreasing from call to call.
            x: inserted length in m (<= 0: outside the body).
            xd: insertion velocity in m/s (negative: retraction).
        Returns:
            the force in N (positive resists insertion). Components in ``self.last``.

        With a compliant shaft (``shaft_stiffness > 0``) x, xd are the drive's; the inserted
        part (``self.y``, ``self.yd``) follows through the shaft spring and the force is the
        vessel's force on it (what a load cell under the phantom measures).
        """
        t = finite('t', t)
        x = finite('x', x)
        xd = finite('xd', xd)
        if self._t_last is None:
            dt = 0.0
        else:
            dt = t - self._t_last
            if dt < 0.0:
                raise ValueError(f't must not decrease: got {t!r} after {self._t_last!r}')
        self._t_last = t
        p = self.params
        if p.shaft_stiffness > 0.0:
            return self._compliant(t, dt, x, xd)
        self.y, self.yd, self._x_last = x, xd, x
        self.last = self._evaluate(t, dt, x, xd)
        return self.last.total

    #: s, largest sub-step of the compliant-shaft integration
    MAX_SUBSTEP = 1e-4

    def _compliant(self, t: float, dt: float, x: float, xd: float) -> float:
        """Drive (x, xd) -> shaft spring-damper -> catheter mass (y, yd) -> vessel force.
        Semi-implicit Euler in sub-steps of at most MAX_SUBSTEP, the drive interpolated."""
        p = self.params
        if self.y is None or dt == 0.0:
            if self.y is None:
                self.y, self.yd = x, xd
            self._x_last = x
            self.last = self._evaluate(t, 0.0, self.y, self.yd)
            return self.last.total
        n = max(1, int(math.ceil(dt / self.MAX_SUBSTEP - 1e-9)))
        h = dt / n
        x0 = self._x_last
        ks, ds, inv_m = p.shaft_stiffness, p.shaft_damping, 1.0 / p.catheter_mass
        y, yd = self.y, self.yd
        comp = self.last
        for k in range(1, n + 1):
            xs = x0 + (x - x0) * (k / n)
            comp = self._evaluate(t - dt + k * h, h, y, yd)
            yd += h * (ks * (xs - y) + ds * (xd - yd) - comp.total) * inv_m
            y += h * yd
        if not (math.isfinite(y) and math.isfinite(yd)):
            raise ValueError('compliant shaft integration diverged: check shaft_stiffness, '
                             'shaft_damping and catheter_mass')
        self.y, self.yd, self._x_last = y, yd, x
        self.last = comp
        return comp.total

    def _evaluate(self, t: float, dt: float, x: float, xd: float) -> VesselForce:
        """Advance the friction state by dt at velocity xd and return the force components at
        inserted length x [m] (of the catheter's inserted part)."""
        p = self.params
        if self._smooth:
            return self._evaluate_smooth(t, x, xd)
        zc = p.presliding_displacement
        # LuGre bristle state, integrated exactly for a velocity held over the step
        # (dz/dt = v - |v| z / (zc g(v)) is linear in z): unconditionally stable at any dt.
        if xd != 0.0:
            g = 1.0 + (p.stribeck_ratio - 1.0) * math.exp(-(xd / p.stribeck_velocity) ** 2)
            a = abs(xd) / (zc * g)
            zss = math.copysign(zc * g, xd)
            if dt > 0.0:
                self.z = zss + (self.z - zss) * math.exp(-a * dt)
            zdot = xd - a * self.z
        else:
            zdot = 0.0
        fc = self.coulomb_force(x)
        friction = fc * (self.z / zc + p.bristle_damping * zdot)
        return self._components(t, x, xd, friction)

    def _evaluate_smooth(self, t: float, x: float, xd: float) -> VesselForce:
        """Stateless smooth Coulomb friction (extras.coulomb_velocity > 0)."""
        p = self.params
        g = 1.0 + (p.stribeck_ratio - 1.0) * math.exp(-(xd / p.stribeck_velocity) ** 2)
        return self._components(t, x, xd, smooth_coulomb(self.extras, self.coulomb_force(x), g, xd))

    def _components(self, t: float, x: float, xd: float, friction: float) -> VesselForce:
        """Drag, contacts and disturbances at (t, x, xd) around a friction force (N)."""
        p = self.params
        xin = x if x > 0.0 else 0.0
        viscous = p.viscous_per_length * xin * xd
        wall = self._wall(x, xd)
        if self._stenosis:
            wall += stenosis_force(self.extras, x)
        cardiac = 0.0
        if xin > 0.0:
            depth = xin / p.cardiac_depth
            ramp = depth if depth < 1.0 else 1.0
            if p.cardiac_amplitude > 0.0:
                cardiac = (p.cardiac_amplitude * ramp * math.sin(
                    2.0 * math.pi * p.cardiac_frequency * t + self.cardiac_phase))
            if self._breathing:
                e = self.extras
                cardiac += e.breathing_amplitude * ramp * math.sin(
                    2.0 * math.pi * e.breathing_frequency * t + self.breathing_phase)
        return VesselForce(friction, viscous, wall, cardiac, friction + viscous + wall + cardiac)
