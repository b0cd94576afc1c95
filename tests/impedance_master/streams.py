"""Identifier input streams shared by the identifier's tests and the ima benchmarks
(tests/bench/bench_ima.py, bench_ima_fuzz.py): one place for how they are recorded; and the
master's pull-back that the renderer's first-reversal tests share."""
from __future__ import annotations

from typing import List, Tuple

Sample = Tuple[float, float, float, float]


def phantom_samples(seconds: float = 12.0, seed: int = 0) -> List[Sample]:
    """(x m, x' m/s, x'' m/s^2, measured f N) of the slave on the phantom following
    Experiment II's operator (seed `seed`) open loop at 1 kHz for `seconds` s."""
    from impedance_master.operator import experiment_trajectory
    from sim_slave.robot import SlaveRobot
    from sim_slave.slave import SlaveSimulation
    traj = experiment_trajectory('II', seed=seed)
    sl = SlaveSimulation(robot=SlaveRobot(x0=traj.sample(0.0)[0]))
    out = []
    for k in range(int(seconds * 1000)):
        s = sl.step(k * 1e-3, traj.sample(k * 1e-3)[0])
        out.append((s.x, s.xd, s.xdd, s.f_meas))
    return out


def experiment_inputs(**cfg) -> List[Sample]:
    """The default identifier's inputs (x, x', x'', f) in a closed-loop experiment
    (`run_experiment(ExperimentConfig(**cfg))`, mode ima), recorded by a subclass swapped in
    for `experiment.make_identifier` during the run."""
    import impedance_master.experiment as experiment
    from impedance_master.history import HistoryIdentifier
    got: List[Sample] = []

    class Rec(HistoryIdentifier):
        def update(self, x, xd, xdd, f):
            got.append((x, xd, xdd, f))
            return super().update(x, xd, xdd, f)

    orig = experiment.make_identifier
    experiment.make_identifier = lambda **kw: Rec(**kw)
    try:
        experiment.run_experiment(experiment.ExperimentConfig(**cfg))
    finally:
        experiment.make_identifier = orig
    return got


def pull_back(ima, x0: float = 0.056, dx: float = 0.002, n: int = 200):
    """The master pulls back from x0 by dx (past the presliding length: friction turned) in n
    calls of `ima.desired_force` at -0.01 m/s; the last desired force (N)."""
    f = None
    for i in range(1, n + 1):
        f = ima.desired_force(x0 - dx * i / n, -0.01, 0.0)
    return f


def insert(ima, m, force, n: int = 93):
    """Feed renderer `ima` the insertion from 10 mm at 10 mm/s in n steps of 0.5 mm, a copy of
    model `m` anchored at each step to the measured force `force(x)` (N); returns `ima`."""
    from impedance_master.impedance import steady_states
    xd = 0.01
    z1, z2 = steady_states(xd, m.v_s, m.beta)
    for i in range(n):
        x = 0.010 + 0.0005 * i
        assert ima.set_impedance(m.copy(anchor=(x, xd, 0.0, z1, z2, force(x), 0.0)))
        ima.desired_force(x, xd, 0.0)
    return ima
