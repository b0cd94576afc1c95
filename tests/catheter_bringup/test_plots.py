"""The run figures on a synthetic recording with known errors: every axes is labelled, no
legend covers an axes' data area, the shaded key is on every figure, the MAE in the legends
is analyze's, the impedance figure shows the tables (typed ImpedanceModel), and the FAM
accuracy plot counts as current only when newer than fam_solver's sources."""
import math
import os
import time

import numpy as np
import pytest
import yaml
from rclpy.serialization import serialize_message

from catheter_bringup import plots
from catheter_bringup.analyze import analyze
from catheter_bringup.recorder import McapRecorder
from catheter_common import messages as Msg


def _wrench(fx, t):
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = int(t // 1), int(round((t % 1) * 1e9))
    m.wrench.force.x = float(fx)
    return m


@pytest.fixture(scope='module')
def run(tmp_path_factory):
    """3 s: slave force, IMA (error 0.01 N, 0.02 N in the outage window [1.2, 1.9) s) and DFR
    (0.05 N) renderers, the slave joint state, and a typed table model at the master; one
    0.5 s outage at 1 s."""
    from sensor_msgs.msg import JointState
    d = tmp_path_factory.mktemp('plots')
    path = d / 'synthetic.mcap'
    sc = {'name': 'synthetic', 'seed': 1, 'link': {'delay': 0.2, 'outages': [[1.0, 0.5]]},
          'metrics': {'skip': 0.2},
          'nodes': {'ima_master_node': {'params': {'mode': 'ima'}},
                    'dfr_master_node': {'executable': 'ima_master_node',
                                        'params': {'mode': 'dfr'},
                                        'remap': {'/master/rendered_force':
                                                  '/master/dfr/rendered_force'}}}}
    rec = McapRecorder(path)
    for topic, kind in (('/slave/force', 'geometry_msgs/msg/WrenchStamped'),
                        ('/master/rendered_force', 'geometry_msgs/msg/WrenchStamped'),
                        ('/master/dfr/rendered_force', 'geometry_msgs/msg/WrenchStamped'),
                        ('/slave/joint_state', 'sensor_msgs/msg/JointState'),
                        ('/master/link/impedance', 'catheter_interfaces/msg/ImpedanceModel')):
        rec.add_topic(topic, kind)
    from impedance_master.impedance import Impedance
    model = Impedance(0.0, 0.1, 0.5, 0.0, True, x0=0.005, dx=0.01, S=[0, 0.1, 0.2],
                      F=[0.05, 0.1, 0.15], B=[0.01, 0.02, 0.03], C=[0.0, 0.1, 0.2])
    for k in range(3001):
        t = k * 1e-3
        ns = k * 1_000_000
        x = 0.01 + 0.01 * math.sin(t)
        rec.write('/slave/force', serialize_message(_wrench(0.2 * math.sin(t), t)), ns)
        sign = 1 if k % 2 else -1
        e_ima = 0.02 if 1.2 <= t < 1.9 else 0.01
        rec.write('/master/rendered_force',
                  serialize_message(_wrench(0.2 * math.sin(t + 0.2) + e_ima * sign, t)), ns)
        rec.write('/master/dfr/rendered_force',
                  serialize_message(_wrench(0.2 * math.sin(t + 0.2) + 0.05 * sign, t)), ns)
        js = JointState(name=['insertion', 'rotation'], position=[x, 0.0],
                        velocity=[0.01 * math.cos(t), 0.0], effort=[0.0, 0.0])
        js.header.stamp = Msg.stamp_msg(ns)
        rec.write('/slave/joint_state', serialize_message(js), ns)
        if k % 10 == 0:
            rec.write('/master/link/impedance', serialize_message(Msg.impedance_msg(
                model, stamp=ns)), ns)
    rec.close('complete', extra={'scenario_yaml': yaml.safe_dump(sc), 'mode': 'lockstep'})
    figs = {}
    orig = plots._save

    def keep(fig, p):
        figs[os.path.basename(str(p))] = fig
        fig.canvas.draw()
        return orig(fig, p)
    plots._save = keep
    try:
        files = plots.run_plots(path, d / 'out')
    finally:
        plots._save = orig
    return path, files, figs


def test_the_three_figures_are_written(run):
    path, files, figs = run
    assert sorted(os.path.basename(f) for f in files) == [
        'synthetic_errors.png', 'synthetic_impedance.png', 'synthetic_tracking.png']
    assert all(os.path.getsize(f) > 20_000 for f in files)


def test_every_axes_is_labelled_and_no_legend_covers_data(run):
    _, _, figs = run
    for name, fig in figs.items():
        for ax in fig.axes:
            if not ax.get_visible():
                continue
            assert ax.get_ylabel(), (name, ax.get_title())
            if ax.get_xlabel() == '' and ax.get_shared_x_axes():
                # a twin axis (velocity) shares the x label of its host
                assert any(o is not ax and o.get_xlabel() for o in fig.axes), name
                continue
            assert ax.get_xlabel(), (name, ax.get_title())
            leg = ax.get_legend()
            if leg is not None:
                a, b = leg.get_window_extent(), ax.get_window_extent()
                overlap = min(a.x1, b.x1) - max(a.x0, b.x0), min(a.y1, b.y1) - max(a.y0, b.y0)
                assert min(overlap) <= 1.0, (name, ax.get_title(), 'legend covers the data')


def test_every_figure_has_the_shading_key(run):
    _, _, figs = run
    for name, fig in figs.items():
        labels = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
        assert any('outage window' in t for t in labels), name
        assert any('not evaluated' in t for t in labels), name
        assert any('link down' in t for t in labels), name


def test_every_time_axes_shades_the_outage_window_and_the_start_up(run):
    """[start + d, start + length + 2 d) = [1.2, 1.9) s and [0, skip = 0.2) s, in every panel
    over time (the impedance tables are over insertion, not time)."""
    _, _, figs = run
    n = 0
    for name, fig in figs.items():
        for ax in fig.axes:
            if ax.get_xlabel() != 'time, s':
                continue
            spans = set()
            for patch in ax.patches:
                if hasattr(patch, 'get_bbox'):                  # Rectangle (data units)
                    x0, x1 = patch.get_bbox().x0, patch.get_bbox().x1
                else:                                           # Polygon
                    xs = np.asarray(patch.get_xy())[:, 0]
                    x0, x1 = xs.min(), xs.max()
                spans.add((round(float(x0), 6), round(float(x1), 6)))
            assert (1.2, 1.9) in spans and (0.0, 0.2) in spans and (1.0, 1.5) in spans, \
                (name, ax.get_title(), spans)
            n += 1
    assert n >= 8


def test_the_legends_carry_analyze_mae_per_interval(run):
    path, _, figs = run
    m = analyze(path)['force_tracking']
    texts = [t.get_text() for ax in figs['synthetic_errors.png'].axes
             if ax.get_legend() for t in ax.get_legend().get_texts()]
    for label in ('ima', 'dfr'):
        want = (f"{label}: MAE normal {m[label]['normal']['mae']:.4f} N, "
                f"outage {m[label]['outage']['mae']:.4f} N")
        assert want in texts, (want, texts)
    assert m['ima']['normal']['mae'] == pytest.approx(0.01, abs=1e-9)
    assert m['ima']['outage']['mae'] == pytest.approx(0.02, abs=1e-9)
    assert m['dfr']['outage']['mae'] == pytest.approx(0.05, abs=1e-9)


def test_the_impedance_figure_shows_the_tables(run):
    _, _, figs = run
    fig = figs['synthetic_impedance.png']
    lines = {ln.get_label(): ln for ax in fig.axes for ln in ax.get_lines()}
    s = lines['S(x) static force']
    np.testing.assert_allclose(s.get_xdata(), [5.0, 15.0, 25.0])      # x0 + i dx, mm
    np.testing.assert_allclose(s.get_ydata(), [0.0, 0.1, 0.2])
    np.testing.assert_allclose(lines['c + C(x) total drag'].get_ydata(), [0.1, 0.2, 0.3])
    ylabels = {ax.get_ylabel() for ax in fig.axes}
    assert {'m, kg', 'c, N s/m', 'k, N/m', 'offset, N', 'force, N', 'drag, N s/m'} <= ylabels


def test_fam_plot_is_current_only_when_newer_than_the_sources(tmp_path):
    from catheter_bringup.fam_plot import FILE, fam_sources_mtime, is_current
    src = fam_sources_mtime()
    assert src is not None
    assert not is_current(tmp_path)                      # missing
    png = tmp_path / FILE
    png.write_bytes(b'x')
    os.utime(png, (src - 10, src - 10))
    assert not is_current(tmp_path)                      # stale
    os.utime(png, (time.time(), time.time()))
    assert is_current(tmp_path)
