"""Status codes: derived from converged / stable / snap_through, consistent everywhere (single
solve, batch, batch.shape(b)), and every outcome reachable and reported."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from fam_solver import Catheter, Loads, Status, globalise, solve_elastica, solve_fam
from fam_solver import solve_fam_batch
from fam_solver.status import status_codes, status_of, warning_text

UNIT = Catheter(1.0, 1.0)
CAT = Catheter(length=0.04, ei=7.5e-4)
SNAP = Loads(tip_force=(5.2968, -4.2802), tip_moment=4.9337)     # fold near 99 % of the load


@given(conv=st.booleans(), stable=st.booleans(), snap=st.booleans())
@settings(max_examples=20, deadline=None)
def test_status_follows_the_flags(conv, stable, snap):
    s = status_of(conv, stable, snap)
    assert (s == Status.NOT_CONVERGED) == (not conv)
    assert (s == Status.UNSTABLE) == (conv and not stable)
    assert (s == Status.SNAP_THROUGH) == (conv and stable and snap)
    assert (s == Status.CONVERGED) == (conv and stable and not snap)
    assert s.message and isinstance(s.message, str)
    assert int(status_codes([conv], [stable], [snap])[0]) == int(s)
    w = warning_text(conv, stable, snap, 1e-3)
    assert (w == '') == (s == Status.CONVERGED)
    assert ('not converged' in w) == (not conv)
    assert ('unstable' in w) == (not stable)


def test_codes_in_the_style_of_scipy():
    assert Status.CONVERGED == 0 and len({int(s) for s in Status}) == len(Status)
    assert len({s.message for s in Status}) == len(Status)


def test_unstable_straight_compression():
    P = 3.0 * np.pi ** 2 / 4 * CAT.ei / CAT.length ** 2
    sh = solve_fam(CAT, Loads(tip_force=(-P, 0.0)), n_arcs=12)
    assert sh.status == Status.UNSTABLE and 'buckling' in sh.warning and sh.status.name in repr(sh)
    bt = solve_fam_batch(CAT, [[-P, 0.0], [0.0, 1.0]], n_arcs=12)
    assert list(bt.status) == [Status.UNSTABLE, Status.CONVERGED]
    assert bt.shape(0).status == Status.UNSTABLE and 'buckling' in bt.shape(0).warning


def test_snap_through_single_and_batch():
    sh = solve_fam(UNIT, SNAP, n_arcs=12)
    assert sh.status == Status.SNAP_THROUGH and sh.snap_through and sh.converged and sh.stable
    bt = solve_fam_batch(UNIT, [list(SNAP.tip_force), [0.0, 1.0]], [SNAP.tip_moment, 0.0],
                         n_arcs=12)
    assert list(bt.snap_through) == [True, False]
    assert list(bt.status) == [Status.SNAP_THROUGH, Status.CONVERGED]
    one = bt.shape(0)
    assert one.status == Status.SNAP_THROUGH and 'snap' in one.warning
    assert np.allclose(one.tip, sh.tip, atol=1e-12)


@pytest.mark.parametrize('n', [12, 100])
def test_not_converged_is_reported_with_finite_numbers(monkeypatch, n):
    """Fault injection: the general path's Newton limited to one iteration (a problem too hard
    for it). Direct attempt, continuation and the snap-through search all fail: the best
    iterate is returned, finite, flagged NOT_CONVERGED with its residual."""
    newton = globalise.newton
    monkeypatch.setattr(globalise, 'MAX_CONTINUATION_ITERS', 30)
    monkeypatch.setattr(globalise, 'newton',
                        lambda prob, phi, scale, max_iter, **kw: newton(prob, phi, scale, 1, **kw))
    ld = Loads(tip_force=(2.0, 30.0), point_forces=((0.5, -40.0, 5.0),))   # general path
    sh = solve_fam(UNIT, ld, n_arcs=n)
    assert not sh.converged and sh.status == Status.NOT_CONVERGED
    assert 'not converged' in sh.warning and f'{sh.residual:.3g}' in sh.warning
    assert np.all(np.isfinite(sh.arc_angles)) and np.all(np.isfinite(sh.tip))
    assert sh.residual > 1e-9
    bt = solve_fam_batch(UNIT, [[2.0, 30.0]], n_arcs=n, arc_model='bezier')
    assert not bt.converged[0] and bt.status[0] == Status.NOT_CONVERGED
    assert np.all(np.isfinite(bt.tips))


def test_reference_rod_has_a_status():
    sh = solve_elastica(UNIT, Loads(tip_force=(0.0, 2.0)))
    assert sh.status == Status.CONVERGED
