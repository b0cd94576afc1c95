"""The generalisation protocol's worlds (issue 12, second round): randomised physical draws
of every vessel family (sim_slave.vessels.draw_vessel) and the fresh held-out cases built
from them (impedance_master.generalisation.drawn_cases). Only the draws are checked here,
never a result on them (the fresh worlds are run once, by bench_ima_general)."""
import math
import random

import pytest

from impedance_master.generalisation import (DEVELOPMENT_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS,
                                             FRESH4_SEEDS, FRESH5_SEEDS, FRESH6_SEEDS,
                                             FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS,
                                             FRESH10_SEEDS, FRESH11_SEEDS, FRESH12_SEEDS,
                                             FRESH13_SEEDS, FRESH14_SEEDS,
                                             FRESH_SEEDS,
                                             drawn_cases)
from impedance_master.operator import OPERATORS
from sim_slave.vessels import DRAW_RULES, VESSELS, draw_vessel, make_vessel, vessel_spec


def test_draws_are_deterministic_and_differ_between_rngs():
    for v in VESSELS:
        a = draw_vessel(v, random.Random('a'))
        assert a == draw_vessel(v, random.Random('a'))
        assert a != draw_vessel(v, random.Random('b'))


def test_draws_keep_the_family_structure_and_stay_in_their_ranges():
    for v in VESSELS:
        base = vessel_spec(v)
        b = base.as_dict()
        for i in range(20):
            d = draw_vessel(v, random.Random(i))
            spec = vessel_spec(v, **d)                     # a valid vessel
            assert set(d) <= set(DRAW_RULES)
            # terms the family does not have stay off
            assert (spec.params.wall_stiffness > 0) == (base.params.wall_stiffness > 0)
            assert spec.extras.stenosis == base.extras.stenosis
            assert (spec.extras.breathing_amplitude > 0) == (base.extras.breathing_amplitude > 0)
            assert (spec.extras.coulomb_velocity > 0) == (base.extras.coulomb_velocity > 0)
            assert (spec.params.shaft_stiffness > 0) == (base.params.shaft_stiffness > 0)
            assert (spec.extras.friction_step > 0) == (base.extras.friction_step > 0)
            for name, value in d.items():
                rule, lo, hi, _ = DRAW_RULES[name]
                if rule == 'scale':
                    assert lo * b[name] * (1 - 1e-12) <= value <= hi * b[name] * (1 + 1e-12)
                elif rule == 'excess':
                    assert 1 + lo * (b[name] - 1) - 1e-12 <= value <= 1 + hi * (b[name] - 1) \
                        + 1e-12
                else:
                    assert lo <= value <= hi, (v, name, value)
            assert 0.005 <= spec.noise_std <= 0.02
            # a clinical force: 0.05-1.5 N at the thesis's deepest point and top speed
            m = make_vessel(v, **{k: x for k, x in d.items() if k != 'noise_std'})
            f = m.steady_force(0.056, 0.0413)
            assert 0.05 < f < 1.5, (v, d, f)


def test_draw_vessel_refuses_bad_arguments():
    with pytest.raises(ValueError, match='vessel must be one of'):
        draw_vessel('aorta', random.Random(0))
    with pytest.raises(ValueError, match='rng must be a random.Random'):
        draw_vessel('soft', 3)


def test_fresh_cases_are_every_family_operator_and_seed_each_its_own_world():
    todo = drawn_cases(FRESH_SEEDS)
    assert len(todo) == len(VESSELS) * len(OPERATORS) * len(FRESH_SEEDS) == 90
    assert {c[0] for c in todo} == set(VESSELS) and {c[1] for c in todo} == set(OPERATORS)
    assert {c[2] for c in todo} == set(FRESH_SEEDS)
    assert len({c[3] for c in todo}) == len(todo)           # no two worlds alike
    # a case's draw does not depend on which other cases are asked for
    one = drawn_cases([FRESH_SEEDS[2]], vessels=('stiff_wall',), operators=('human',))
    assert one[0] in todo
    for _v, _op, _s, params in todo[:3]:
        assert all(math.isfinite(x) for _, x in params)


def test_second_fresh_set_is_new_worlds_disjoint_from_every_seen_seed():
    assert not set(FRESH2_SEEDS) & (set(FRESH_SEEDS) | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH2_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for c in drawn_cases(FRESH_SEEDS)}
    assert not {c[3] for c in todo} & seen               # no world of the first draw again


def test_third_fresh_set_is_new_worlds_disjoint_from_every_seen_seed():
    assert not set(FRESH3_SEEDS) & (set(FRESH_SEEDS) | set(FRESH2_SEEDS)
                                    | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH3_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for c in drawn_cases(FRESH_SEEDS) + drawn_cases(FRESH2_SEEDS)}
    assert not {c[3] for c in todo} & seen


def test_fourth_fresh_set_is_new_worlds_disjoint_from_every_seen_seed():
    assert not set(FRESH4_SEEDS) & (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS)
                                    | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH4_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for c in drawn_cases(FRESH_SEEDS) + drawn_cases(FRESH2_SEEDS)
            + drawn_cases(FRESH3_SEEDS)}
    assert not {c[3] for c in todo} & seen


def test_fifth_fresh_set_is_new_worlds_disjoint_from_every_seen_seed():
    seen_seeds = (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS) | set(FRESH4_SEEDS)
                  | set(DEVELOPMENT_SEEDS))
    assert not set(FRESH5_SEEDS) & seen_seeds
    todo = drawn_cases(FRESH5_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS)
            for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_sixth_fresh_set_is_new_worlds_disjoint_from_every_seen_seed():
    seen_seeds = (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS) | set(FRESH4_SEEDS)
                  | set(FRESH5_SEEDS) | set(DEVELOPMENT_SEEDS))
    assert not set(FRESH6_SEEDS) & seen_seeds
    todo = drawn_cases(FRESH6_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS)
            for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_seventh_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    seen_seeds = (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS) | set(FRESH4_SEEDS)
                  | set(FRESH5_SEEDS) | set(FRESH6_SEEDS) | set(DEVELOPMENT_SEEDS))
    assert not set(FRESH7_SEEDS) & seen_seeds
    todo = drawn_cases(FRESH7_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
                           FRESH6_SEEDS)
            for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_eighth_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    seen_seeds = (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS) | set(FRESH4_SEEDS)
                  | set(FRESH5_SEEDS) | set(FRESH6_SEEDS) | set(FRESH7_SEEDS)
                  | set(DEVELOPMENT_SEEDS))
    assert not set(FRESH8_SEEDS) & seen_seeds
    todo = drawn_cases(FRESH8_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
                           FRESH6_SEEDS, FRESH7_SEEDS)
            for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_ninth_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    seen_seeds = (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS) | set(FRESH4_SEEDS)
                  | set(FRESH5_SEEDS) | set(FRESH6_SEEDS) | set(FRESH7_SEEDS)
                  | set(FRESH8_SEEDS) | set(DEVELOPMENT_SEEDS))
    assert not set(FRESH9_SEEDS) & seen_seeds
    todo = drawn_cases(FRESH9_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
                           FRESH6_SEEDS, FRESH7_SEEDS, FRESH8_SEEDS)
            for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_tenth_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    seen_seeds = (set(FRESH_SEEDS) | set(FRESH2_SEEDS) | set(FRESH3_SEEDS) | set(FRESH4_SEEDS)
                  | set(FRESH5_SEEDS) | set(FRESH6_SEEDS) | set(FRESH7_SEEDS)
                  | set(FRESH8_SEEDS) | set(FRESH9_SEEDS) | set(DEVELOPMENT_SEEDS))
    assert not set(FRESH10_SEEDS) & seen_seeds
    todo = drawn_cases(FRESH10_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
                           FRESH6_SEEDS, FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS)
            for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_eleventh_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    earlier = (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
               FRESH6_SEEDS, FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS, FRESH10_SEEDS)
    assert not set(FRESH11_SEEDS) & (set().union(*earlier) | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH11_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in earlier for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_twelfth_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    earlier = (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
               FRESH6_SEEDS, FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS, FRESH10_SEEDS,
               FRESH11_SEEDS)
    assert not set(FRESH12_SEEDS) & (set().union(*earlier) | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH12_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in earlier for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen


def test_thirteenth_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    earlier = (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
               FRESH6_SEEDS, FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS, FRESH10_SEEDS,
               FRESH11_SEEDS, FRESH12_SEEDS)
    assert not set(FRESH13_SEEDS) & (set().union(*earlier) | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH13_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in earlier for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen



def test_fourteenth_fresh_set_is_new_worlds_disjoint_from_every_seen_and_held_out_seed():
    earlier = (FRESH_SEEDS, FRESH2_SEEDS, FRESH3_SEEDS, FRESH4_SEEDS, FRESH5_SEEDS,
               FRESH6_SEEDS, FRESH7_SEEDS, FRESH8_SEEDS, FRESH9_SEEDS, FRESH10_SEEDS,
               FRESH11_SEEDS, FRESH12_SEEDS, FRESH13_SEEDS)
    assert not set(FRESH14_SEEDS) & (set().union(*earlier) | set(DEVELOPMENT_SEEDS))
    todo = drawn_cases(FRESH14_SEEDS)
    assert len(todo) == 90
    seen = {c[3] for s in earlier for c in drawn_cases(s)}
    assert not {c[3] for c in todo} & seen

# ---- issue 12's criterion and case results, by hand (mutation sweep W09-W12)
def test_beats_dfr_needs_all_three_parts():
    from impedance_master.generalisation import CaseResult, beats_dfr
    dfr = CaseResult(normal=0.08, outage=0.20, all=0.1, max=0.6)
    assert beats_dfr(CaseResult(0.01, 0.09, 0.03, 0.3), dfr)
    assert not beats_dfr(CaseResult(0.08, 0.09, 0.03, 0.3), dfr)     # normal not below
    assert not beats_dfr(CaseResult(0.01, 0.10, 0.03, 0.3), dfr)     # outage not below half
    assert not beats_dfr(CaseResult(0.01, 0.15, 0.03, 0.3), dfr)     # below DFR, above half
    assert not beats_dfr(CaseResult(0.01, 0.09, 0.03, 0.6), dfr)     # largest error not below


def test_case_result_takes_the_largest_error_of_both_intervals():
    from impedance_master.generalisation import case_result
    m = {'normal': {'mae': 0.01, 'max': 0.05}, 'outage': {'mae': 0.02, 'max': 0.3},
         'all': {'mae': 0.012, 'max': 0.3}}
    r = case_result(m)
    assert (r.normal, r.outage, r.all, r.max) == (0.01, 0.02, 0.012, 0.3)
    m['normal']['max'] = 0.4
    assert case_result(m).max == 0.4


def test_held_out_cases_leave_the_tuning_family_out():
    from impedance_master.generalisation import TUNING, cases
    held = cases([1, 2])
    assert len(held) == (len(VESSELS) * len(OPERATORS) - 1) * 2
    assert not any((v, op) == TUNING for v, op, _ in held)
    every = cases([1, 2], include_tuning=True)
    assert sum((v, op) == TUNING for v, op, _ in every) == 2
    assert set(held) < set(every)
