"""The family of simulated vessels, selectable by name (scenario YAML, ExperimentConfig,
benchmarks): vessels that differ in STRUCTURE (friction law and its growth with length,
wall model, disturbances, sensor noise), so that an identifier tuned on one of them can be
tried on the others.

    from sim_slave.vessels import make_vessel, vessel_spec, VESSELS
    v = make_vessel('stribeck_kv', seed=0)            # a VesselModel
    v = make_vessel('phantom', seed=0, wall_depth=0.05)   # any field overridden by name
    spec = vessel_spec('soft')                        # VesselSpec(name, params, extras, noise_std)
    spec.build(seed=3); spec.sensor(seed=4)           # the vessel and its force sensor

Names (steady forces quoted at 56 mm and 41.3 mm/s, the thesis's deepest point and top
speed, without disturbances and noise: `VesselModel.steady_force`):

* ``phantom`` (alias ``default``): the project's phantom, `VesselParams()` unchanged: LuGre
  friction growing super-linearly with length (capstan), Stribeck breakaway 1.4x, viscous
  drag, Hunt-Crossley wall past 45 mm, 10 mN cardiac; sensor noise 10 mN. About 0.40 N.
* ``smooth_coulomb``: Coulomb friction smooth in velocity (stateless tanh, 3 mm/s scale, no
  stick and nothing held at rest) growing LINEARLY with length, strong viscous drag, a
  Hunt-Crossley wall past 38 mm, 8 mN cardiac; noise 5 mN. About 0.44 N.
* ``stribeck_kv``: friction growing with the SQUARE of the length, a pronounced Stribeck
  bump (1.8x below 3 mm/s) and genuine stick-slip (compliant shaft 150 N/m: the inserted
  part lags the drive by up to ~1.7 mm and sticks/slips at slow speed), a Kelvin-Voigt
  tissue wall (spring 6 N/m and damper 1.5 N s/m) past 30 mm, breathing (20 mN, 0.25 Hz)
  and cardiac (10 mN); noise 10 mN. About 0.49 N.
* ``stenosis``: friction in STEPS (+0.04 N every 12 mm: side branches and valves passed)
  on a small linear base, a sudden stiff stenosis at 34 mm (3 mm long, a 0.12 N
  conservative bump that resists entry and pushes the tip on past its narrowest point,
  +0.05 N friction once the shaft lies in it), no wall, cardiac 10 mN; noise 15 mN.
* ``soft``: a soft, compliant vessel: the vessel bed moves with the catheter for 2.5 mm
  before it slides (large presliding), linear friction, a soft Kelvin-Voigt wall from
  20 mm (4 N/m, 0.5 N s/m), strong breathing (30 mN) and cardiac (12 mN); noise 20 mN.
* ``stiff_wall``: a static-dominated vessel: little friction (linear, 1 N/m), a stiff
  linear wall contact from 25 mm (12 N/m, Hunt-Crossley exponent 1): the same force
  whichever way the catheter moves; noise 5 mN. About 0.44 N.

Randomised worlds (`draw_vessel(family, rng)`): a new physical draw of a family, keeping
its structure (which terms are present) and drawing every parameter of it within the
physical range documented in `DRAW_RULES` (for held-out worlds of a generalisation test:
`impedance_master.generalisation`).
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass, fields, replace
from typing import Dict, Optional, Tuple

from catheter_common.checks import nonneg, seed as check_seed
from sim_slave.sensor import ForceSensor
from sim_slave.vessel import VesselModel, VesselParams
from sim_slave.vessel_extras import VesselExtras


@dataclass(frozen=True)
class VesselSpec:
    """A selected vessel: its name, parameters, structure terms and force-sensor noise (N).

    `build(seed)` makes the (stateful) `VesselModel`; `sensor(seed)` the matching
    `ForceSensor`. Frozen and comparable, so a config can hold it.
    """
    name: str
    params: VesselParams
    extras: VesselExtras
    noise_std: float

    def build(self, seed: Optional[int] = 0) -> VesselModel:
        return VesselModel(self.params, seed=seed, extras=self.extras)

    def sensor(self, seed: Optional[int] = 0) -> ForceSensor:
        return ForceSensor(noise_std=self.noise_std, seed=seed)

    def as_dict(self) -> dict:
        """Every parameter by name (VesselParams, VesselExtras and noise_std)."""
        d = self.params.as_dict()
        d.update(self.extras.as_dict())
        d['noise_std'] = self.noise_std
        return d


# name -> (VesselParams overrides, VesselExtras overrides, sensor noise N)
_FAMILY: Dict[str, Tuple[dict, dict, float]] = {
    'phantom': ({}, {}, 0.01),
    'smooth_coulomb': (
        dict(friction_per_length=4.0, capstan_length=1e3, stribeck_ratio=1.0,
             viscous_per_length=30.0, wall_depth=0.038, wall_stiffness=60.0,
             wall_exponent=1.5, wall_damping=1.0, cardiac_amplitude=0.008),
        dict(coulomb_velocity=0.003), 0.005),
    'stribeck_kv': (
        dict(friction_per_length=0.0, stribeck_ratio=1.8, stribeck_velocity=0.003,
             presliding_displacement=5e-5, viscous_per_length=10.0, wall_depth=0.030,
             wall_stiffness=6.0, wall_exponent=1.0, wall_damping=0.0,
             cardiac_amplitude=0.01, shaft_stiffness=150.0, shaft_damping=0.3,
             catheter_mass=0.005),
        dict(friction_quadratic=80.0, wall_viscous=1.5, breathing_amplitude=0.02,
             breathing_frequency=0.25), 0.01),
    'stenosis': (
        dict(friction_per_length=1.5, capstan_length=1e3, wall_stiffness=0.0,
             cardiac_amplitude=0.01),
        dict(friction_step=0.04, friction_step_spacing=0.012, stenosis_depth=0.034,
             stenosis_length=0.003, stenosis_force=0.12, stenosis_friction=0.05), 0.015),
    'soft': (
        dict(friction_per_length=3.5, capstan_length=1e3, presliding_displacement=2.5e-3,
             bristle_damping=0.05, viscous_per_length=15.0, wall_depth=0.020,
             wall_stiffness=4.0, wall_exponent=1.0, wall_damping=0.0,
             cardiac_amplitude=0.012),
        dict(wall_viscous=0.5, breathing_amplitude=0.03, breathing_frequency=0.25), 0.02),
    'stiff_wall': (
        dict(friction_per_length=1.0, capstan_length=1e3, viscous_per_length=5.0,
             wall_depth=0.025, wall_stiffness=12.0, wall_exponent=1.0, wall_damping=0.2),
        {}, 0.005),
}
_ALIASES = {'default': 'phantom'}

#: the vessel names of the family (aliases not repeated)
VESSELS: Tuple[str, ...] = tuple(_FAMILY)

_PARAM_NAMES = frozenset(f.name for f in fields(VesselParams))
_EXTRA_NAMES = frozenset(f.name for f in fields(VesselExtras))


def vessel_names() -> Tuple[str, ...]:
    """Every accepted name (family names, then aliases)."""
    return VESSELS + tuple(_ALIASES)


def vessel_spec(name: str = 'phantom', **overrides) -> VesselSpec:
    """The named vessel with any VesselParams / VesselExtras field or ``noise_std`` (N)
    overridden. ValueError naming the unknown name or field."""
    key = _ALIASES.get(name, name) if isinstance(name, str) else None   # a list: no TypeError
    if key not in _FAMILY:
        raise ValueError(f'vessel must be one of {vessel_names()}, got {name!r}')
    base, extra, noise = _FAMILY[key]
    p_kw, e_kw = dict(base), dict(extra)
    for k, v in overrides.items():
        if k in _PARAM_NAMES:
            p_kw[k] = v
        elif k in _EXTRA_NAMES:
            e_kw[k] = v
        elif k == 'noise_std':
            noise = v
        else:
            raise ValueError(f'unknown vessel parameter {k!r} (VesselParams, VesselExtras '
                             'fields or noise_std)')
    return VesselSpec(key, replace(VesselParams(), **p_kw), replace(VesselExtras(), **e_kw),
                      nonneg('noise_std', noise))


#: How `draw_vessel` draws each parameter of a family's vessel: field -> (rule, a, b, why).
#: Rules: 'scale' multiplies the family's value by a log-uniform factor in [a, b] (only
#: terms the family has, value > 0); 'depth' draws the depth uniformly in [a, b] m (only if
#: the family has that contact); 'uniform' draws the value uniformly in [a, b] (always);
#: 'excess' scales the excess over 1 of a ratio by a uniform factor in [a, b]. The ranges
#: are physical: forces stay in the clinical 0.1-1 N at 56 mm, lengths and rates in what
#: catheters, vessels, hearts and lungs show.
DRAW_RULES = {
    'friction_per_length': ('scale', 0.6, 1.6, 'Coulomb level: catheter coating, wet or dry '
                            'lumen, vessel tortuosity'),
    'capstan_length': ('uniform', 0.05, 0.30, 'm, capstan growth (only a capstan family)'),
    'friction_quadratic': ('scale', 0.6, 1.6, 'quadratic friction growth (more wrapped bends)'),
    'friction_step': ('scale', 0.6, 1.6, 'N per side branch or valve passed'),
    'friction_step_spacing': ('uniform', 0.008, 0.016, 'm between side branches'),
    'stribeck_ratio': ('excess', 0.5, 1.5, 'static over kinetic friction 1.1-2.2'),
    'stribeck_velocity': ('scale', 0.5, 2.0, 'm/s, 1-6 mm/s Stribeck scale'),
    'presliding_displacement': ('scale', 0.5, 2.0, 'm, shaft / vessel-bed compliance'),
    'coulomb_velocity': ('scale', 0.5, 2.0, 'm/s, smooth Coulomb velocity scale'),
    'viscous_per_length': ('scale', 0.5, 2.0, 'drag: blood or saline film, lumen gap'),
    'wall_depth': ('depth', 0.018, 0.048, 'm, where the tip meets the wall or a bend'),
    'wall_stiffness': ('scale', 0.6, 1.6, 'tissue stiffness'),
    'wall_damping': ('scale', 0.5, 2.0, 'Hunt-Crossley damping'),
    'wall_viscous': ('scale', 0.5, 2.0, 'Kelvin-Voigt damper of the tissue'),
    'stenosis_depth': ('depth', 0.026, 0.046, 'm, where the narrowing is'),
    'stenosis_length': ('scale', 0.7, 1.5, 'm, 2-6 mm narrowing'),
    'stenosis_force': ('scale', 0.6, 1.6, 'N, how tight the narrowing is'),
    'stenosis_friction': ('scale', 0.6, 1.6, 'N, friction of the shaft in it'),
    'shaft_stiffness': ('scale', 0.5, 2.0, 'N/m, shaft compliance (stick-slip)'),
    'cardiac_amplitude': ('uniform', 0.005, 0.015, 'N, cardiac disturbance'),
    'cardiac_frequency': ('uniform', 1.0, 1.7, 'Hz, 60-100 beats per minute'),
    'breathing_amplitude': ('scale', 0.5, 1.5, 'N, breathing disturbance (if the family '
                            'breathes)'),
    'breathing_frequency': ('uniform', 0.2, 0.33, 'Hz, 12-20 breaths per minute (if the family '
                            'breathes)'),
    'noise_std': ('uniform', 0.005, 0.02, 'N, force-sensor noise (issue 12: 5-20 mN)'),
}


def draw_vessel(family: str, rng: random.Random) -> Dict[str, float]:
    """A randomised physical draw of the named family (see `DRAW_RULES`): the overrides to
    pass to `vessel_spec(family, **overrides)` (or `ExperimentConfig.vessel_params`). The
    family's structure is kept: terms it does not have stay off. rng: a `random.Random`
    (the draw is a deterministic function of its state)."""
    spec = vessel_spec(family)
    if not isinstance(rng, random.Random):
        raise ValueError(f'rng must be a random.Random, got {type(rng).__name__}')
    base = spec.as_dict()
    has = {'wall_depth': spec.params.wall_stiffness > 0.0,
           'stenosis_depth': spec.extras.stenosis,
           'stenosis_length': spec.extras.stenosis,
           'capstan_length': base['capstan_length'] < 1.0 and base['friction_per_length'] > 0,
           'breathing_frequency': base['breathing_amplitude'] > 0.0,
           'friction_step_spacing': base['friction_step'] > 0.0}
    out = {}
    for name, (rule, a, b, _) in DRAW_RULES.items():   # fixed order: one rng draw per rule
        u = rng.random()
        v = base[name]
        if not has.get(name, True):
            continue
        if rule == 'scale':
            if v > 0.0:
                out[name] = v * math.exp(math.log(a) + u * (math.log(b) - math.log(a)))
        elif rule == 'excess':
            if v > 1.0:
                out[name] = 1.0 + (v - 1.0) * (a + u * (b - a))
        else:                                           # 'depth' and 'uniform'
            out[name] = a + u * (b - a)
    vessel_spec(family, **out)                          # every draw is a valid vessel
    return dict(sorted(out.items()))


def make_vessel(name: str = 'phantom', seed: Optional[int] = 0, **overrides) -> VesselModel:
    """A `VesselModel` of the named vessel (see the module doc), fields overridden by name."""
    return vessel_spec(name, **overrides).build(check_seed('seed', seed))
