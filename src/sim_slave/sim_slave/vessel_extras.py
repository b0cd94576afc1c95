"""Vessel physics beyond the project's phantom (`VesselParams`): the terms that make the
other vessels of the family (`sim_slave.vessels`) differ in STRUCTURE, not only in size.

Every term is off by default, so ``VesselModel(params)`` without extras is exactly the
project's phantom. Pure functions of the inserted length x (m) and velocity x' (m/s); the
stateful parts (friction state, time) stay in `VesselModel`.

* friction growing **quadratically** with length (``friction_quadratic``) or in **steps**
  (``friction_step`` N every ``friction_step_spacing`` m: each side branch or valve passed
  adds wrap and contact), on top of VesselParams' capstan-like growth;
* **smooth Coulomb** friction (``coulomb_velocity > 0``): ``Fc(x) g(x') tanh(x' / v_c)``,
  stateless (no presliding, no memory at rest), instead of the LuGre bristle state;
* a **Kelvin-Voigt** tissue wall (``wall_viscous``: ``+ b d'`` on the contact, a spring
  and a damper in parallel; with ``wall_exponent = 1`` and ``wall_damping = 0`` it is the
  plain Kelvin-Voigt contact ``k d + b d'``, clipped at zero: the wall never pulls);
* a **stenosis**: a narrowing of length ``stenosis_length`` at ``stenosis_depth`` that the
  tip must squeeze through. A conservative potential bump ``U(d) = F L / (2 pi)
  (1 - cos(2 pi d / L))`` (d = x - depth in [0, L]): the force ``F sin(2 pi d / L)``
  resists entry and pushes the tip on once past the narrowest point (so it is NOT always
  >= 0), plus ``stenosis_friction`` N of extra Coulomb level once the shaft lies in it;
* **breathing**: a ``breathing_frequency`` sinusoid of ``breathing_amplitude`` N, ramped in
  with depth like the cardiac term (the heart and lungs move the vessel bed).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from catheter_common.checks import CheckedFields, checked


@dataclass(frozen=True)
class VesselExtras(CheckedFields):
    """Structure terms added to a `VesselParams` vessel (SI units; all off by default).

    Attributes:
        friction_quadratic: N/m^2, 0. Extra Coulomb level ``a x^2`` (friction growing with
            the square of the inserted length: more bends wrapped the deeper it goes).
        friction_step: N, 0. Coulomb level added at each multiple of
            ``friction_step_spacing`` (a side branch, valve or introducer section passed).
        friction_step_spacing: m, 0.015. Distance between steps (> 0).
        friction_step_width: m, 5e-4. Length over which one step rises (smoothstep, > 0).
        coulomb_velocity: m/s, 0 = LuGre bristle friction (VesselParams). > 0: stateless
            smooth Coulomb friction ``Fc(x) g(x') tanh(x' / coulomb_velocity)`` with the
            Stribeck factor g of VesselParams (no presliding stick, nothing held at rest).
        wall_viscous: N s/m, 0. Kelvin-Voigt damper ``b d'`` added to the wall contact.
        stenosis_depth: m, 0 = no stenosis. Inserted length at which the tip enters it.
        stenosis_length: m, 0.004. Length of the narrowing (> 0).
        stenosis_force: N, 0. Peak force of the potential bump (resisting on entry,
            pushing the tip on past the narrowest point).
        stenosis_friction: N, 0. Extra Coulomb level once the shaft lies in the stenosis
            (a smooth step over the stenosis's second half).
        breathing_amplitude: N, 0. Amplitude of the breathing disturbance.
        breathing_frequency: Hz, 0.25 (15 breaths per minute, > 0).
    """

    friction_quadratic: float = checked(0.0, 'nonneg')
    friction_step: float = checked(0.0, 'nonneg')
    friction_step_spacing: float = checked(0.015, 'positive')
    friction_step_width: float = checked(5e-4, 'positive')
    coulomb_velocity: float = checked(0.0, 'nonneg')
    wall_viscous: float = checked(0.0, 'nonneg')
    stenosis_depth: float = checked(0.0, 'nonneg')
    stenosis_length: float = checked(0.004, 'positive')
    stenosis_force: float = checked(0.0, 'nonneg')
    stenosis_friction: float = checked(0.0, 'nonneg')
    breathing_amplitude: float = checked(0.0, 'nonneg')
    breathing_frequency: float = checked(0.25, 'positive')

    @property
    def friction_terms(self) -> bool:
        """True if any term adds to the Coulomb level."""
        return (self.friction_quadratic > 0.0 or self.friction_step > 0.0
                or (self.stenosis_depth > 0.0 and self.stenosis_friction > 0.0))

    @property
    def stenosis(self) -> bool:
        return self.stenosis_depth > 0.0 and (self.stenosis_force > 0.0
                                              or self.stenosis_friction > 0.0)


#: (lower bound, upper bound, unit and meaning) of each VesselExtras field, for node
#: parameter declarations (the node exposes them as `vessel.<field>`)
EXTRAS_PARAM_INFO = {
    'friction_quadratic': (0.0, 1e4, 'N/m^2, Coulomb level growing with length squared'),
    'friction_step': (0.0, 10.0, 'N, Coulomb level added per step'),
    'friction_step_spacing': (1e-4, 1.0, 'm, distance between friction steps'),
    'friction_step_width': (1e-5, 0.1, 'm, length over which a step rises'),
    'coulomb_velocity': (0.0, 1.0, 'm/s, smooth Coulomb friction scale (0: LuGre)'),
    'wall_viscous': (0.0, 1e3, 'N s/m, Kelvin-Voigt damper of the wall'),
    'stenosis_depth': (0.0, 1.0, 'm, depth of the stenosis (0: none)'),
    'stenosis_length': (1e-4, 0.1, 'm, length of the stenosis'),
    'stenosis_force': (0.0, 10.0, 'N, peak force of the stenosis bump'),
    'stenosis_friction': (0.0, 10.0, 'N, extra friction inside the stenosis'),
    'breathing_amplitude': (0.0, 1.0, 'N, breathing disturbance amplitude'),
    'breathing_frequency': (0.01, 2.0, 'Hz, breathing rate'),
}


def smoothstep(u: float) -> float:
    """0 for u <= 0, 1 for u >= 1, 3u^2 - 2u^3 between (C1)."""
    if u <= 0.0:
        return 0.0
    if u >= 1.0:
        return 1.0
    return u * u * (3.0 - 2.0 * u)


def extra_friction(e: VesselExtras, x: float) -> float:
    """Coulomb level in N added by the extras at inserted length x >= 0 (m)."""
    fc = e.friction_quadratic * x * x
    if e.friction_step > 0.0:
        s = e.friction_step_spacing
        n = math.floor(x / s)
        if n >= 1:
            fc += e.friction_step * ((n - 1) + smoothstep((x - n * s) / e.friction_step_width))
    if e.stenosis_friction > 0.0 and e.stenosis_depth > 0.0:
        half = 0.5 * e.stenosis_length
        fc += e.stenosis_friction * smoothstep((x - e.stenosis_depth - half) / half)
    return fc


def stenosis_force(e: VesselExtras, x: float) -> float:
    """Static (conservative) force in N of the stenosis bump at inserted length x (m)."""
    if e.stenosis_force <= 0.0 or e.stenosis_depth <= 0.0:
        return 0.0
    d = x - e.stenosis_depth
    if d <= 0.0 or d >= e.stenosis_length:
        return 0.0
    return e.stenosis_force * math.sin(2.0 * math.pi * d / e.stenosis_length)


def smooth_coulomb(e: VesselExtras, fc: float, g: float, xd: float) -> float:
    """Stateless smooth Coulomb friction in N: level fc (N), Stribeck factor g, velocity xd."""
    return fc * g * math.tanh(xd / e.coulomb_velocity)
