"""`sim_slave.vessels.draw_vessel` maps each uniform number through the rule DRAW_RULES
documents ('scale': a log-uniform factor in [a, b]; 'uniform' / 'depth': uniform in [a, b];
'excess': the excess over 1 scaled by a uniform factor), and keeps the family's structure:
a family whose friction grows linearly is never given a capstan."""
import math
import random

import pytest

from sim_slave.vessels import DRAW_RULES, VESSELS, draw_vessel, vessel_spec


class FixedU(random.Random):
    """An rng whose every uniform number is u."""

    def __init__(self, u):
        super().__init__(0)
        self.u = u

    def random(self):
        return self.u


def test_the_middle_draw_is_the_geometric_middle_of_a_scale_rule():
    """u = 0.5: a log-uniform factor in [a, b] is sqrt(a b) (a uniform one would be
    (a + b) / 2); the phantom's viscous drag (rule 0.5-2) is drawn unchanged."""
    d = draw_vessel('phantom', FixedU(0.5))
    base = vessel_spec('phantom').as_dict()
    assert d['viscous_per_length'] == pytest.approx(base['viscous_per_length'])
    for name, value in d.items():
        rule, a, b, _ = DRAW_RULES[name]
        if rule == 'scale':
            assert value == pytest.approx(base[name] * math.sqrt(a * b), rel=1e-12), name
        elif rule == 'excess':
            assert value == pytest.approx(1.0 + (base[name] - 1.0) * (a + b) / 2), name
        else:
            assert value == pytest.approx((a + b) / 2, rel=1e-12), name


@pytest.mark.parametrize('u', [0.0, 0.25, 0.999999])
def test_a_scale_factor_is_a_power_of_its_range(u):
    """The factor of a 'scale' rule is a^(1-u) b^u: a at u = 0, b as u -> 1."""
    d = draw_vessel('stribeck_kv', FixedU(u))
    base = vessel_spec('stribeck_kv').as_dict()
    _, a, b, _ = DRAW_RULES['shaft_stiffness']                    # 0.5-2
    assert d['shaft_stiffness'] == pytest.approx(
        base['shaft_stiffness'] * a ** (1 - u) * b ** u, rel=1e-9)


def test_only_a_capstan_family_gets_a_capstan_length():
    """Only the phantom's friction grows with a capstan (0.10 m); the others grow linearly
    (capstan 1 km, i.e. none) or quadratically without a Coulomb level: drawn worlds of them
    keep that growth law."""
    for seed in range(5):
        drawn = [v for v in VESSELS if 'capstan_length' in draw_vessel(v, random.Random(seed))]
        assert drawn == ['phantom']
    for v in VESSELS:
        if v != 'phantom':
            d = draw_vessel(v, random.Random(1))
            assert vessel_spec(v, **d).params.capstan_length == vessel_spec(v).params \
                .capstan_length, v
