"""force_tracking leaves the start-up (`skip` seconds after t0) out of every interval."""
import numpy as np
import pytest

from catheter_bringup.metrics import force_tracking


@pytest.mark.parametrize('skip', [0.5, 1.0])
def test_start_up_errors_are_left_out_of_every_interval(skip):
    t = np.arange(0.0, 3.0, 0.001)
    f_slave = 0.2 * np.sin(t)
    f_master = 0.2 * np.sin(t + 0.1) + 0.01        # delay 0.1 s, 10 mN off ...
    f_master[t < skip] += 1.0                       # ... and a 1 N transient at start-up
    res = force_tracking(t, f_master, t, f_slave, delay=0.1, outages=[(1.5, 0.3)],
                         skip=skip)
    for part in ('all', 'normal', 'outage'):
        assert res[part]['max'] == pytest.approx(0.01, abs=1e-9), part
    assert res['all']['n'] == int(np.sum((t >= skip) & (t + 0.1 <= t[-1])))
    assert force_tracking(t, f_master, t, f_slave, delay=0.1, skip=0.0)['all']['max'] \
        == pytest.approx(1.01, abs=1e-9)
