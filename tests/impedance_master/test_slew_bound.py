"""Issue 12's bound on what reaches the hand: the rendered force changes by at most 0.01 N per
1 ms period with the default configuration, also in drawn worlds where the model's force jumps
(at 20 N/s, the previous default, phantom x minjerk seed 202 stepped 0.02 N in one period)."""
import numpy as np

from impedance_master.experiment import ExperimentConfig, run_experiment
from impedance_master.generalisation import drawn_cases
from impedance_master.rendering import SAFE_MAX_RATE
from impedance_master.ima_master_node import PARAMS


def _case(vessel, operator, seed):
    for v, op, s, vp in drawn_cases([seed], vessels=(vessel,), operators=(operator,)):
        return ExperimentConfig(mode='ima', vessel=v, operator=op, seed=s, vessel_params=vp)


def test_default_slew_bound_is_one_hundredth_newton_per_ms():
    assert SAFE_MAX_RATE * 1e-3 <= 0.01
    assert ExperimentConfig().max_rate == SAFE_MAX_RATE
    assert {p.name: p.default for p in PARAMS}['max_rate'] == SAFE_MAX_RATE


def test_largest_step_per_ms_within_bound_where_the_model_jumps():
    cfg = _case('phantom', 'minjerk', 202)
    fast = run_experiment(cfg, max_rate=20.0).series['f_desired']
    assert np.max(np.abs(np.diff(fast))) > 0.0101     # the world does jump (not a vacuous test)
    f = run_experiment(cfg).series['f_desired']
    assert np.all(np.isfinite(f))
    assert np.max(np.abs(np.diff(f))) <= SAFE_MAX_RATE * 1e-3 + 1e-12
