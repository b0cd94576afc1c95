"""The FAM accuracy-against-time figure of the main command: the data converge (the tip
error against solve_elastica falls with the arc count), the figure is written and then
counts as current until a fam_solver module is newer."""
import os

import numpy as np
import pytest

from catheter_bringup import fam_plot


def test_fam_accuracy_data_converge_and_the_figure_is_current_once_drawn(tmp_path):
    d = fam_plot.fam_accuracy_data(n_arcs=(2, 8, 24), alphas=(1.0, 5.0), repeats=1)
    assert d['n_arcs'] == [2, 8, 24]
    err = np.array(d['error_frac_l'])
    assert np.all(np.isfinite(err)) and np.all(np.diff(err) < 0)   # converges with N
    assert err[-1] < 1e-3                                          # 0.1 % L at 24 arcs
    assert all(t > 0 for t in d['time_s'])
    assert not fam_plot.is_current(tmp_path)                       # nothing drawn yet
    path = fam_plot.fam_accuracy_plot(tmp_path, data={'clothoid': d})
    assert path == str(tmp_path / fam_plot.FILE)
    with open(path, 'rb') as f:
        assert f.read(8) == b'\x89PNG\r\n\x1a\n'
    assert fam_plot.is_current(tmp_path)
    src = fam_plot.fam_sources_mtime()
    os.utime(path, (src - 10, src - 10))                            # older than the sources
    assert not fam_plot.is_current(tmp_path)
    assert fam_plot.fam_accuracy_plot(tmp_path, data={'clothoid': None}) is None


def test_the_error_is_the_worst_over_the_loads_as_a_fraction_of_the_length():
    """Each point is the largest tip error over the loads, divided by the catheter's length
    (the figure's axis is % of L), as fam_solver itself gives them."""
    from fam_solver import Catheter, Loads, solve_elastica, solve_fam
    alphas = (1.0, 10.0)
    d = fam_plot.fam_accuracy_data(n_arcs=(2,), alphas=alphas, repeats=1)
    cat = Catheter(length=0.065, ei=6.0e-5)
    errs = []
    for a in alphas:
        loads = Loads(tip_force=(0.0, a * cat.ei / cat.length ** 2))
        ref = np.asarray(solve_elastica(cat, loads).tip)
        tip = np.asarray(solve_fam(cat, loads, n_arcs=2, arc_model='clothoid',
                                   spacing='uniform').tip)
        errs.append(float(np.linalg.norm(tip - ref)))
    assert errs[0] != errs[1]
    assert d['error_frac_l'] == [pytest.approx(max(errs) / cat.length, rel=1e-9)]
