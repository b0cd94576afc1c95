"""catheter_topic (list, echo, hz, bw on live DDS topics; info for a bag) against a lockstep run
started with `run_scenario --dds` in another process: its topics are seen and their messages
arrive outside the process; without --dds they do not."""
import math
import os
import pathlib
import signal
import subprocess
import sys
import pytest

from catheter_bringup import topic_tool

REF = pathlib.Path(__file__).resolve().parents[2] / 'bags' / 'reference'


def _start(*extra):
    cmd = [sys.executable, '-m', 'catheter_bringup.run_scenario', 'smoke', '--duration', '300',
           '--no-record', '--quiet', *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=dict(os.environ))


def _stop(proc):
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode


@pytest.fixture
def dds_run():
    proc = _start('--dds')
    try:
        # the run is up once its topics are in the graph (start-up imports take seconds)
        session = topic_tool._Session()
        try:
            up = session.topic_type('/slave/force', 60.0)
        finally:
            session.close()
        assert up and proc.poll() is None, proc.stdout.read() if proc.poll() is not None else ''
        yield proc
    finally:
        code = _stop(proc)
        assert code == 0


@pytest.mark.ros
@pytest.mark.slow
def test_list_echo_hz_bw_see_a_lockstep_run_published_with_dds(dds_run, capsys):
    # a new DDS participant discovers the run within the --wait time; sometimes it takes
    # longer (seen in full suites and, about one run in four, alone: the list then showed only
    # the tool's own topics for 12 s): ask again, for up to 45 s
    import time
    deadline = time.monotonic() + 45.0
    while True:
        assert topic_tool.main(['list', '-t', '--wait', '3']) == 0
        listed = capsys.readouterr().out.splitlines()
        if ('/slave/force [geometry_msgs/msg/WrenchStamped]' in listed
                or time.monotonic() > deadline):
            break
    assert '/slave/force [geometry_msgs/msg/WrenchStamped]' in listed
    assert '/master/rendered_force [geometry_msgs/msg/WrenchStamped]' in listed

    assert topic_tool.main(['echo', '/slave/force', '--count', '2', '--timeout', '20']) == 0
    out = capsys.readouterr().out
    assert out.count('---') >= 2 and 'wrench:' in out and "frame_id: 'catheter_base'" in out

    assert topic_tool.main(['hz', '/slave/force', '--duration', '2', '--stamps']) == 0
    out = capsys.readouterr().out
    # the lockstep clock: one message per 1 ms step of simulated time
    assert 'average rate: 1000.000 Hz (header stamps)' in out

    assert topic_tool.main(['hz', '/slave/force', '--duration', '1.0']) == 0
    assert 'average rate: ' in capsys.readouterr().out

    assert topic_tool.main(['bw', '/master/rendered_force', '--duration', '1.5']) == 0
    out = capsys.readouterr().out
    from geometry_msgs.msg import WrenchStamped
    from catheter_bringup.ros_recording import exact_bytes
    msg = WrenchStamped()
    msg.header.frame_id = 'catheter_base'
    size = len(exact_bytes(msg))                                # 84 B on the wire
    assert 'KB/s from' in out and f'mean: {size} B' in out


@pytest.mark.ros
def test_an_unknown_topic_is_reported(capsys):
    assert topic_tool.main(['echo', '/no/such/topic', '--timeout', '0.5']) == 1
    assert 'no such topic' in capsys.readouterr().err


@pytest.mark.ros
@pytest.mark.slow
def test_without_dds_a_lockstep_run_sends_nothing_outside(capsys):
    proc = _start()
    try:
        session = topic_tool._Session()
        try:
            assert session.topic_type('/slave/force', 60.0)      # advertised, but ...
        finally:
            session.close()
        assert topic_tool.main(['hz', '/slave/force', '--duration', '2', '--timeout', '3']) == 1
    finally:
        assert _stop(proc) == 0


def test_info_describes_a_bag(capsys):
    assert topic_tool.main(['info', str(REF / 'reference_outage.mcap')]) == 0
    out = capsys.readouterr().out
    assert 'Duration:          1.999 s' in out and 'Messages:          8000' in out
    assert 'Run:               reference_outage (complete)' in out
    line = next(x for x in out.splitlines() if x.strip().startswith('/slave/force'))
    assert line.split()[1:] == ['geometry_msgs/msg/WrenchStamped', '2000', 'msgs',
                                'best_effort']
    assert topic_tool.main(['info', str(REF / 'missing.mcap')]) == 2
    assert 'no such file' in capsys.readouterr().err


def test_echo_format_and_rate_statistics():
    from sensor_msgs.msg import Image, JointState
    lines = topic_tool.to_yaml(JointState(name=['a'], position=[0.5]))
    assert lines[:3] == ['header:', '  stamp:', '    sec: 0'] and "name: ['a']" in lines
    img = topic_tool.to_yaml(Image(height=2, width=20, encoding='mono8', data=bytes(40)))
    assert "data: '<sequence of 40 values>'" in img
    assert len([ln for ln in topic_tool.to_yaml(Image(data=bytes(40)), full=True)
                if ln.startswith('data: [')]) == 1
    st = topic_tool.rate_stats([0.0, 0.001, 0.002, 0.004])
    assert st['rate_hz'] == pytest.approx(1000 * 3 / 4) and st['max'] == pytest.approx(0.002)
    assert st['min'] == pytest.approx(0.001) and st['n'] == 3
    assert math.isnan(topic_tool.rate_stats([1.0])['rate_hz'])


def test_echo_shows_the_typed_messages_field_by_field():
    """catheter_topic echo on the graph's typed topics: the impedance model's scalars,
    tables and anchor, the command's acceleration, the estimate's status and covariance."""
    from catheter_common import messages as M
    from impedance_master.impedance import Impedance
    model = Impedance(0.1, 2.0, 3.0, 0.5, True, x0=0.01, dx=0.005, S=[1, 2], F=[4, 5],
                      B=[7, 8], C=[1, 2], status='ok', anchor=(0.03, 0.01, 0.2, 1, 1.5, 0.25,
                                                               -0.01))
    lines = topic_tool.to_yaml(M.impedance_msg(model, stamp=5))
    for want in ('kind: 1', 'c: 2.0', 's_table: [1.0, 2.0]', 'has_anchor: true',
                 'anchor_f: 0.25', "status: 'ok'"):
        assert want in lines, (want, lines)
    assert 'acceleration: 0.4' in topic_tool.to_yaml(M.master_command_msg(0.03, 0.01, 0.4))
    est = topic_tool.to_yaml(M.tip_force_msg((0.01, 0.02), [[1e-4, 0], [0, 4e-4]],
                                             'unobservable_axial', 'fam_fallback', 0.0))
    assert 'status: 4' in est and "method: 'fam_fallback'" in est


def test_echo_shows_sequences_up_to_show_max_and_every_field_of_listed_messages():
    """Sequences of up to SHOW_MAX values are printed (longer ones as their length); each
    message of a sequence of messages is printed with all its nested fields."""
    from geometry_msgs.msg import Pose, PoseArray
    from sensor_msgs.msg import JointState
    n = topic_tool.SHOW_MAX
    lines = topic_tool.to_yaml(JointState(position=[float(k) for k in range(n)]))
    assert f'position: {[float(k) for k in range(n)]}' in lines
    lines = topic_tool.to_yaml(JointState(position=[0.0] * (n + 1)))
    assert f"position: '<sequence of {n + 1} values>'" in lines
    poses = [Pose(), Pose()]
    poses[0].position.x, poses[1].position.z, poses[1].orientation.w = 0.5, -2.0, 0.25
    lines = topic_tool.to_yaml(PoseArray(poses=poses))
    at = lines.index('poses:')
    items = lines[at + 1:]
    starts = [k for k, ln in enumerate(items) if ln.startswith('- ')]
    assert starts == [0, len(items) // 2] and items[0] == '- position:'
    first, second = items[:starts[1]], items[starts[1]:]
    assert '    x: 0.5' in first and '    z: -2.0' in second and '    w: 0.25' in second
    assert sum(ln.strip().startswith(('x:', 'y:', 'z:', 'w:')) for ln in items) == 2 * 7
