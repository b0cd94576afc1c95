"""Benchmark of the running system (catheter_bringup): prints tables of what, this project, the
reference measured in the same run, and the ratio.

    scripts/bench system            # or: python tests/bench/bench_system.py [--quick]

1. Lockstep: the 12 s Experiment II scenario (whatever of its graph exists) on the 1 ms simulated
   clock: real-time factor with the in-process bus, with and without recording; reference: the
   same graph in lockstep through DDS (waiting for delivery each step), 1.5 s.
2. Real time: the Experiment II graph on the system clock for 5 s (in-process bus, timers called
   when due): period p50/p99/max of the 1 kHz loops from their header stamps; references: one
   bare 1 kHz timer node (EventsExecutor), and the same graph through DDS with an
   EventsExecutor.
3. Image -> tip force latency (real time): synthetic 640x480 frames at 30 Hz -> shape_node ->
   force_estimator_node (method fam: needs no trained model): p50/p99 of (arrival of
   /catheter/tip_wrench - the image's stamp).
4. Recorder: write throughput of McapRecorder (pre-serialised CDR) against mcap_ros2's Writer
   (reference); lost messages when a publisher in the same process runs at 1, 5 and 20 kHz and
   the recorder subscribes through DDS (real time).
The machine has 2 cores shared with other work: timings are noisy.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[2]
for pkg in sorted((ROOT / 'src').iterdir()):
    if (pkg / 'package.xml').exists() and str(pkg) not in sys.path:
        sys.path.insert(0, str(pkg))
os.environ.setdefault('CATHETER_WS_ROOT', str(ROOT))

from catheter_common.ros_testing import isolate_ros_env  # noqa: E402

isolate_ros_env()

ROWS = []


def row(what, ours, ref, unit='', ratio=None, fmt='{:.3g}'):
    r = ratio if ratio is not None else (ours / ref if ref and np.isfinite(ref) and ref != 0
                                         else float('nan'))
    ROWS.append((what, fmt.format(ours) + unit, (fmt.format(ref) + unit) if ref is not None
                 and np.isfinite(ref) else '-', f'{r:.2f}' if np.isfinite(r) else '-'))


def note(what, text):
    ROWS.append((what, text, '', ''))


def table():
    w = max(len(r[0]) for r in ROWS) + 2
    print(f"{'what':<{w}} {'this project':>16} {'reference':>16} {'ratio':>7}")
    for a, b, c, d in ROWS:
        print(f'{a:<{w}} {b:>16} {c:>16} {d:>7}')


def lockstep(duration, quick):
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    with tempfile.TemporaryDirectory() as tmp:
        sc = load_scenario('experiment_ii')
        sc['duration'] = duration
        r = ScenarioRunner(sc, bag=f'{tmp}/a.mcap', progress=False, log=lambda *_: None).run()
        nodes = ', '.join(r.nodes)
        row(f'lockstep {duration:g} s Exp. II, recorded: real-time factor', r.realtime_factor,
            1.0, 'x', fmt='{:.2f}')
        row('  messages recorded / lost', sum(r.recorded.values()), None, '', ratio=float('nan'),
            fmt='{:.0f}')
        ROWS[-1] = (ROWS[-1][0], f'{sum(r.recorded.values())} / {sum(r.lost.values())}', '', '')
        sc = load_scenario('experiment_ii')
        sc['duration'] = duration
        r2 = ScenarioRunner(sc, record=False, progress=False, log=lambda *_: None).run()
        row(f'lockstep {duration:g} s Exp. II, not recorded: real-time factor',
            r2.realtime_factor, 1.0, 'x', fmt='{:.2f}')
        sc = load_scenario('experiment_ii')
        sc['duration'] = 1.5 if not quick else 0.5
        sc['lockstep_transport'] = 'dds'
        r3 = ScenarioRunner(sc, record=False, progress=False, log=lambda *_: None).run()
        row('lockstep via DDS (reference transport): real-time factor', r3.realtime_factor,
            r2.realtime_factor, 'x', fmt='{:.2f}')
        note('  nodes in the lockstep graph', nodes)
        if r.skipped:
            note('  not available (not measured)', ', '.join(r.skipped))


def realtime(duration):
    from catheter_bringup.analyze import Recording
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    with tempfile.TemporaryDirectory() as tmp:
        sc = load_scenario('experiment_ii')
        sc['duration'] = duration
        sc['mode'] = 'realtime'
        sc['record']['only'] = ['/master/rendered_force', '/slave/force', '/master/command',
                                '/slave/joint_state', '/master/dfr/rendered_force']
        r = ScenarioRunner(sc, bag=f'{tmp}/rt.mcap', progress=False, log=lambda *_: None).run()
        rec = Recording(f'{tmp}/rt.mcap', decode=False)
        ref = bare_timer(duration)
        for topic in sc['record']['only']:
            st = rec.stamps(topic)
            if st.size < 10:
                continue
            d = np.diff(st[len(st) // 10:]) * 1e3   # leave out the start-up tenth
            row(f'real time 1 kHz {topic}: period p50', float(np.percentile(d, 50)),
                ref[0], ' ms', fmt='{:.3f}')
            row('    period p99 (target <= 1.5 ms)', float(np.percentile(d, 99)), ref[1], ' ms',
                fmt='{:.3f}')
            row('    period max', float(d.max()), ref[2], ' ms', fmt='{:.2f}')
            row('    rate', (len(st) - 1) / (st[-1] - st[0]), 1000.0, ' Hz', fmt='{:.0f}')
        lost = sum(r.lost.values())
        note('  real-time run: recorded / lost',
             f'{sum(r.recorded.values())} / {lost}')
        # the same graph through DDS with an EventsExecutor (reference transport)
        sc = load_scenario('experiment_ii')
        sc['duration'] = duration
        sc['mode'] = 'realtime'
        sc['realtime_transport'] = 'dds'
        sc['record']['only'] = ['/master/rendered_force']
        ScenarioRunner(sc, bag=f'{tmp}/dds.mcap', progress=False, log=lambda *_: None).run()
        st = Recording(f'{tmp}/dds.mcap', decode=False).stamps('/master/rendered_force')
        ours = Recording(f'{tmp}/rt.mcap', decode=False).stamps('/master/rendered_force')
        if st.size > 10 and ours.size > 10:
            d = np.diff(st[len(st) // 10:]) * 1e3
            o = np.diff(ours[len(ours) // 10:]) * 1e3
            row('real time /master/rendered_force p99: local bus vs DDS transport',
                float(np.percentile(o, 99)), float(np.percentile(d, 99)), ' ms', fmt='{:.3f}')
            row('real time /master/rendered_force rate: local bus vs DDS transport',
                (ours.size - 1) / (ours[-1] - ours[0]), (st.size - 1) / (st[-1] - st[0]),
                ' Hz', fmt='{:.0f}')


def bare_timer(duration):
    """p50, p99, max period (ms) of a lone 1 kHz timer node spun by an EventsExecutor loop."""
    import rclpy
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('bare_timer', context=ctx)
    stamps = []
    node.create_timer(0.001, lambda: stamps.append(node.get_clock().now().nanoseconds))
    ex = EventsExecutor(context=ctx)
    ex.add_node(node)
    end = time.monotonic() + min(duration, 3.0)
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    ex.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    d = np.diff(np.asarray(stamps[len(stamps) // 10:], dtype=float)) * 1e-6
    return float(np.percentile(d, 50)), float(np.percentile(d, 99)), float(d.max())


def image_latency(duration):
    try:
        from catheter_shape.shape_node import NODE_CLASS as Shape
        from catheter_shape.camera import SyntheticCamera
        from force_estimator.force_estimator_node import NODE_CLASS as Est
        from fam_solver import Catheter, Loads, solve_fam
    except ImportError as exc:
        note('image -> tip force latency', f'not measured ({exc.name} missing)')
        return
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Image
    from catheter_common import topics as T
    from catheter_common import qos as Q
    cam = SyntheticCamera(seed=1)
    cat = Catheter(length=0.065, ei=6.0e-5)
    frames = []
    for k in range(8):
        ang = np.pi * k / 8
        f = 0.15 * np.array([np.cos(ang), np.sin(ang)])
        shape = solve_fam(cat, Loads(tip_force=tuple(f)), n_arcs=12)
        frames.append(cam.render(shape.centerline(200)).image)
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        # a 640x480 camera: its calibration, not shape_node's default (the 800x800 system camera)
        shape = Shape(context=ctx, parameter_overrides=[
            Parameter('psi', value=[float(v) for v in cam.psi.reshape(-1)]),
            Parameter('base_px', value=[float(v) for v in cam.base_px])])
        est = Est(context=ctx, parameter_overrides=[Parameter('method', value='fam')])
    except Exception as exc:  # noqa: BLE001
        note('image -> tip force latency', f'not measured ({type(exc).__name__}: {exc})')
        rclpy.try_shutdown(context=ctx)
        return
    src = rclpy.create_node('bench_camera', context=ctx)
    pub = src.create_publisher(Image, T.CAMERA_IMAGE, Q.QOS_SENSOR)
    lat = []

    def on_wrench(msg):
        now = src.get_clock().now().nanoseconds
        lat.append((now - (msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)) * 1e-6)
    src.create_subscription(WrenchStamped, T.TIP_WRENCH, on_wrench, Q.QOS_SENSOR)
    k = [0]

    def tick():
        img = Image()
        img.header.stamp = src.get_clock().now().to_msg()
        img.header.frame_id = T.FRAME_CAMERA
        a = frames[k[0] % len(frames)]
        img.height, img.width = a.shape
        img.encoding, img.step = 'mono8', a.shape[1]
        img.data = a.tobytes()
        pub.publish(img)
        k[0] += 1
    src.create_timer(1 / 30, tick)
    ex = EventsExecutor(context=ctx)
    for n in (shape, est, src):
        ex.add_node(n)
    end = time.monotonic() + duration
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    ex.shutdown()
    for n in (shape, est, src):
        n.destroy_node()
    rclpy.try_shutdown(context=ctx)
    lat = np.asarray(lat[2:])
    if lat.size == 0:
        note('image -> tip force latency', f'no estimate arrived ({k[0]} frames sent)')
        return
    row('image -> tip force latency p50 (640x480, fam)', float(np.percentile(lat, 50)),
        1000 / 30, ' ms', fmt='{:.1f}')
    row('image -> tip force latency p99 (ref: frame period)', float(np.percentile(lat, 99)),
        1000 / 30, ' ms', fmt='{:.1f}')
    row('  estimates per frame sent', lat.size / max(k[0] - 2, 1), 1.0, '', fmt='{:.2f}')


def recorder_throughput(quick):
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import serialize_message
    from catheter_bringup.recorder import McapRecorder
    n = 20000 if quick else 100000
    msg = WrenchStamped()
    msg.header.frame_id = 'catheter_base'
    data = serialize_message(msg)
    with tempfile.TemporaryDirectory() as tmp:
        rec = McapRecorder(f'{tmp}/w.mcap')
        rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
        t = time.perf_counter()
        for i in range(n):
            rec.write('/slave/force', data, i * 1000)
        rec.close()
        ours = n / (time.perf_counter() - t)
        from mcap_ros2.writer import Writer
        from catheter_bringup.recorder import message_definition
        with open(f'{tmp}/r.mcap', 'wb') as f:
            w = Writer(f)
            schema = w.register_msgdef('geometry_msgs/msg/WrenchStamped',
                                       message_definition('geometry_msgs/msg/WrenchStamped'))
            d = {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': 'catheter_base'},
                 'wrench': {'force': {'x': 0.0, 'y': 0.0, 'z': 0.0},
                            'torque': {'x': 0.0, 'y': 0.0, 'z': 0.0}}}
            m = n // 5
            t = time.perf_counter()
            for i in range(m):
                w.write_message('/slave/force', schema, d, log_time=i * 1000, publish_time=i * 1000)
            w.finish()
            ref = m / (time.perf_counter() - t)
    row('recorder write throughput (CDR bytes in)', ours, ref, ' msg/s', fmt='{:.0f}')


def recorder_loss(rate, seconds):
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.context import Context
    from rclpy.experimental import EventsExecutor
    from catheter_bringup.recorder import McapRecorder
    from catheter_bringup.ros_recording import RecordingSink
    from catheter_common.qos import QOS_DEFAULT
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('bench_rec', context=ctx)
    pub = node.create_publisher(WrenchStamped, '/bench/force', QOS_DEFAULT)
    with tempfile.TemporaryDirectory() as tmp:
        rec = McapRecorder(f'{tmp}/l.mcap')
        sink = RecordingSink(node, rec)
        sink.add('/bench/force', 'geometry_msgs/msg/WrenchStamped', [QOS_DEFAULT])
        msg = WrenchStamped()
        sent = [0]
        per_tick = max(1, int(rate / 1000))

        def tick():
            for _ in range(per_tick):
                msg.wrench.force.x = float(sent[0])
                pub.publish(msg)
                sent[0] += 1
        timer = node.create_timer(per_tick / rate, tick)
        ex = EventsExecutor(context=ctx)
        ex.add_node(node)
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            ex.spin_once(timeout_sec=0.05)
        node.destroy_timer(timer)
        t_end = time.monotonic() + 2.0
        while sink.received['/bench/force'] < sent[0] and time.monotonic() < t_end:
            ex.spin_once(timeout_sec=0.05)
        rec.close()
        got = rec.counts['/bench/force']
    ex.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    ROWS.append((f'recorder via DDS at {rate / 1000:g} kHz (reliable): sent / recorded / lost',
                 f'{sent[0]} / {got} / {sent[0] - got}', f'{int(rate * seconds)} asked', ''))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('--quick', action='store_true', help='short runs (a smoke test of the bench)')
    a = ap.parse_args()
    print(f'bench_system on {os.cpu_count()} cores (shared; timings noisy)')
    lockstep(3.0 if a.quick else 12.0, a.quick)
    realtime(2.0 if a.quick else 5.0)
    image_latency(2.0 if a.quick else 5.0)
    recorder_throughput(a.quick)
    for rate in (1000, 5000, 20000):
        recorder_loss(rate, 1.0 if a.quick else 2.0)
    table()


if __name__ == '__main__':
    main()
