"""Benchmark of the running system (catheter_bringup): prints tables of what, this project, the
reference measured in the same run, and the ratio.

    scripts/bench system            # or: python tests/bench/bench_system.py [--quick]
    python tests/bench/bench_system.py --split-only     # part 2 alone (and its costs)

1. Lockstep: the 12 s Experiment II scenario (whatever of its graph exists) on the 1 ms simulated
   clock: real-time factor with the in-process bus and the vision chain in a process of its
   own (the default) against the one-process run (``lockstep_processes: 1``) of the same
   session, with and without recording; the CPU each process used per simulated second;
   recorded without the vision chain (its image outputs left out, so camera, shape and
   estimator do not run); reference: the same graph in lockstep through DDS (waiting for
   delivery each step), 1.5 s. After the table: each node's callback time per simulated
   second (both recorded runs).
2. Real time, the split layout (master / slave / vision processes over DDS, each recording
   its own nodes' messages, merged into the bag by the runner) beside the one-process layout
   (reference), on the machine as it is ("quiet") and with a busy-loop process occupying one
   core ("loaded"), 6 s of Experiment II
   each with 5 % injected link loss: rate and period p50/p99/max of every 1 kHz stream,
   measured where it is published; image -> tip force latency in the vision process; what
   DDS lost on the link topics (from the header stamps both ends saw) against the injected
   loss; recorder loss; GC, scheduling and CPU placement per process; the CPU each process
   used while its loop ran (by thread) against the one process; reference: a lone 1 kHz
   timer.
3. Image -> tip force latency alone: synthetic 800x800 frames of the system camera at 30 Hz ->
   shape_node -> force_estimator_node (svr; fam when no model is installed).
4. Recorder: write throughput of McapRecorder (pre-serialised CDR) against mcap_ros2's Writer
   (reference); lost messages when a publisher in the same process runs at 1, 5 and 20 kHz and
   the recorder subscribes through DDS (real time).
5. Where the time goes (after the table): callback cost per node in both layouts (quiet run),
   serialise / deserialise / construct per message.
The machine has 2 cores shared with other work: timings are noisy.
"""
from __future__ import annotations

import argparse
import contextlib
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

from catheter_bringup.stall_probe import StallProbe, coinciding  # noqa: E402
from catheter_common.ros_testing import isolate_ros_env  # noqa: E402

isolate_ros_env()

ROWS = []
#: run the machine stall probe beside the real-time runs (--probe; off by default: on the
#: benchmark VM its 1 kHz wake-ups on every CPU slowed the one-process reference by 10-20 %
#: and drew the host's 100 ms holds)
PROBE = False
#: scenario overrides of every real-time run (--set)
EXTRA_SETS: list = []


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


def _lockstep_run(duration, bag=None, **fields):
    """One lockstep Experiment II run; returns (RunResult, CPU s per simulated s of this
    process, of the vision process's loop, of the recording's writer process)."""
    import resource
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    sc = load_scenario('experiment_ii')
    sc['duration'] = duration
    sc.update(fields)
    r = ScenarioRunner(sc, bag=bag, record=bag is not None, progress=False,
                       log=lambda *_: None)
    r.setup()
    ch0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    c0 = time.process_time()
    res = r.run()
    cpu = time.process_time() - c0
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    children = ch.ru_utime + ch.ru_stime - ch0.ru_utime - ch0.ru_stime
    vis = res.processes.get('vision', {})
    writer = children - (vis.get('cpu_total_s') or 0.0)
    return res, cpu / duration, (vis.get('cpu_s') or 0.0) / duration, writer / duration


def lockstep(duration, quick):
    """Lockstep rows: the default (the vision chain in a process of its own,
    `catheter_bringup.lockstep_peer`) against the one-process run (``lockstep_processes:
    1``) in the same session, recorded and not; without the vision chain; through DDS."""
    with tempfile.TemporaryDirectory() as tmp:
        r, c_main, c_vis, c_wr = _lockstep_run(duration, f'{tmp}/a.mcap')
        r1, c1_main, _c, c1_wr = _lockstep_run(duration, f'{tmp}/b.mcap', lockstep_processes=1)
        nodes = ', '.join(r.nodes)
        row(f'lockstep {duration:g} s Exp. II, recorded: real-time factor (vision process '
            'vs one process)', r.realtime_factor, r1.realtime_factor, 'x', fmt='{:.2f}')
        row(f'lockstep {duration:g} s Exp. II, recorded, one process: real-time factor',
            r1.realtime_factor, 1.0, 'x', fmt='{:.2f}')
        ROWS.append(('  messages recorded / lost (vision process; one process)',
                     f'{sum(r.recorded.values())} / {sum(r.lost.values())}',
                     f'{sum(r1.recorded.values())} / {sum(r1.lost.values())}', ''))
        ROWS.append(('  CPU s per simulated s: main / vision loop / writer',
                     f'{c_main:.2f} / {c_vis:.2f} / {c_wr:.2f}', f'{c1_main:.2f} / - / '
                     f'{c1_wr:.2f}', ''))
        vis = r.processes.get('vision', {})
        note('  vision process: wait for it at the end of the run',
             f"{vis.get('wait_at_end_s', float('nan')):.2f} s")
        LOCK.append(r)
        LOCK.append(r1)
        rv, *_ = _lockstep_run(duration, f'{tmp}/nv.mcap', outputs=[
            t for t in _vision_free_outputs()])
        row(f'lockstep {duration:g} s Exp. II without the vision chain (outputs: no image '
            'topics), recorded', rv.realtime_factor, r.realtime_factor, 'x', fmt='{:.2f}')
        note('    its nodes', ', '.join(rv.nodes))
        r2, *_ = _lockstep_run(duration)
        r21, *_ = _lockstep_run(duration, lockstep_processes=1)
        row(f'lockstep {duration:g} s Exp. II, not recorded: real-time factor (vision '
            'process vs one process)', r2.realtime_factor, r21.realtime_factor, 'x',
            fmt='{:.2f}')
        r3, *_ = _lockstep_run(1.5 if not quick else 0.5, lockstep_transport='dds')
        row('lockstep via DDS (reference transport): real-time factor', r3.realtime_factor,
            r2.realtime_factor, 'x', fmt='{:.2f}')
        note('  nodes in the lockstep graph', nodes)
        if r.skipped:
            note('  not available (not measured)', ', '.join(r.skipped))


def _vision_free_outputs():
    from catheter_bringup.scenario import load_scenario
    return [t for t in load_scenario('experiment_ii')['outputs'] if t not in VISION_OUTPUTS]


#: the outputs of Experiment II that only the vision chain (camera, shape, estimator) makes
VISION_OUTPUTS = {'/catheter/tip_wrench', '/catheter/tip_force', '/catheter/control_points',
                  '/camera/tip_force_truth'}
#: the recorded lockstep runs, vision process and one process (for "where the time goes")
LOCK = []


#: the 1 kHz streams, the process that publishes them in the split layout, and which are
#: the master's force loop (the loaded-machine target applies to those)
STREAMS = [('/master/rendered_force', 'master', True), ('/master/command', 'master', True),
           ('/master/hand_force', 'master', True), ('/master/dfr/rendered_force', 'master', False),
           ('/slave/force', 'slave', False), ('/slave/joint_state', 'slave', False),
           ('/slave/impedance', 'slave', False)]
#: injected link loss of the real-time runs (the link model drops it after DDS delivered)
INJECTED_LOSS = 0.05


class CpuLoad:
    """A busy-loop subprocess occupying one core while in the `with` block."""

    def __enter__(self):
        import subprocess
        self.proc = subprocess.Popen([sys.executable, '-c', 'while True: pass'])
        return self

    def __exit__(self, *exc):
        self.proc.kill()
        self.proc.wait()


def realtime_run(layout, duration, tmp, record=()):
    """One real-time Experiment II run; returns (stream stats by topic, the RunResult).
    record: topics recorded besides the 1 kHz streams and /catheter/tip_wrench (the bag:
    <tmp>/rt_<layout>.mcap)."""
    from catheter_bringup.overrides import apply_overrides
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    sets = ['mode=realtime', f'duration={duration}', f'link.loss={INJECTED_LOSS}',
            f'layout={layout}'] + list(EXTRA_SETS)
    if layout == 'one':
        sets.append('realtime_processes=1')          # every node in this one process
    sc = apply_overrides(load_scenario('experiment_ii'), sets)
    sc['record']['only'] = [t for t, _, _ in STREAMS] + ['/catheter/tip_wrench'] + list(record)
    r = ScenarioRunner(sc, bag=f'{tmp}/rt_{layout}.mcap', progress=False,
                       log=lambda *_: None).run()
    streams, lat = {}, {}
    reps = [rep.get('realtime', {}) for k, rep in r.processes.items() if k != 'link']
    for rt in reps + [r.realtime]:
        streams.update(rt.get('streams', {}))
        lat.update(rt.get('latency', {}))
    return streams, lat, r


def cpu_share(rt):
    """CPU s per s of loop (1.0 = one core) from a process's real-time report (NaN without)."""
    cpu, loop = rt.get('cpu_s'), rt.get('loop_s')
    return cpu / loop if cpu is not None and loop else float('nan')


def realtime(duration):
    """The split layout beside the one-process layout, quiet and with one core busy."""
    import tempfile as tf
    runs, probes = {}, {}
    with tf.TemporaryDirectory() as tmp:
        for load in ('quiet', 'loaded'):
            for layout in ('one', 'split'):
                with contextlib.ExitStack() as stack:
                    if load == 'loaded':
                        stack.enter_context(CpuLoad())
                    probe = stack.enter_context(StallProbe()) if PROBE else None
                    runs[load, layout] = realtime_run(layout, duration, tmp)
                probes[load, layout] = probe
    ref = bare_timer(duration)
    for load in ('quiet', 'loaded'):
        note(f'-- real time {duration:g} s Exp. II, {load}'
             + (' (a busy-loop process on one core)' if load == 'loaded' else '')
             + ': split layout (this project) vs one process (reference)', '')
        (s_split, lat_split, r_split) = runs[load, 'split']
        (s_one, lat_one, r_one) = runs[load, 'one']
        for topic, proc, force_loop in STREAMS:
            a, b = s_split.get(topic), s_one.get(topic)
            if a is None:
                note(f'{topic}', 'not published (node missing)')
                continue
            b = b or {'rate_hz': float('nan'), 'p50_ms': float('nan'), 'p99_ms': float('nan')}
            if load == 'quiet':
                tgt_r, tgt_p = '>= 995 Hz', '<= 1.5 ms'
            elif force_loop:
                tgt_r, tgt_p = '>= 990 Hz', '<= 2 ms'
            else:
                tgt_r = tgt_p = 'no target'
            row(f'{topic} ({proc}) rate, target {tgt_r}', a['rate_hz'], b['rate_hz'], ' Hz',
                fmt='{:.1f}')
            row('    period p50', a['p50_ms'], b['p50_ms'], ' ms', fmt='{:.3f}')
            row(f'    period p99, target {tgt_p}', a['p99_ms'], b['p99_ms'], ' ms', fmt='{:.3f}')
            row('    period max', a['max_ms'], b.get('max_ms', float('nan')), ' ms', fmt='{:.2f}')
            probe = probes[load, 'split']
            if probe is not None and a.get('gaps') is not None:
                gaps = a['gaps']
                cpus = r_split.processes.get(proc, {}).get('cpus')
                hit = coinciding(gaps, probe.stalls_on(cpus))
                lost = sum(round(g[1]) - 1 for g in gaps)
                lost_hit = sum(round(g[1]) - 1 for g, h in zip(gaps, hit, strict=True) if h)
                note('    gaps > 2 ms: n (ticks missed), of them in a machine stall of '
                     + (f'CPU {cpus}' if cpus else 'a CPU'),
                     f'{len(gaps)} ({lost}), {sum(hit)} ({lost_hit})'
                     + (f"; longest {max(g[1] for g in gaps):.1f} ms at "
                        f"{gaps[int(np.argmax([g[1] for g in gaps]))][0] - probe.t_start:.2f} s"
                        if gaps else ''))
        probe = probes[load, 'split']
        if probe is not None:
            sm = probe.summary()
            cpus = sorted(probe.stalls)
            note('  machine stalls in the split run (probe: SCHED_FIFO 99 per CPU, wake-ups '
                 '> 1 ms late): n / longest per CPU, on every CPU at once',
                 ', '.join(f"cpu{c} {sm[f'cpu{c}_n']} / {sm[f'cpu{c}_max_ms']:.1f} ms"
                           for c in cpus)
                 + (f", together {sm['together']}" if 'together' in sm else '')
                 + f" in {sm['span_s']:.1f} s ({'; '.join(sorted(set(probe.scheduling.values())))})"
                 + (f'; probe errors: {probe.errors}' if probe.errors else ''))
        lt = lat_split.get('/catheter/tip_wrench')
        lo = lat_one.get('/catheter/tip_wrench')
        if lt and lt['n'] > 0:
            row('image -> tip force latency p99 (in the vision process), target <= 33 ms',
                lt['p99_ms'], lo['p99_ms'] if lo and lo['n'] else float('nan'), ' ms',
                fmt='{:.1f}')
            note('    estimates (split / one)', f"{lt['n']} / {lo['n'] if lo else 0}")
            probe = probes[load, 'split']
            if probe is not None and lt.get('slow') is not None:
                cpus = r_split.processes.get('vision', {}).get('cpus')
                hit = coinciding(lt['slow'], probe.stalls_on(cpus))
                note('    estimates over 33 ms, of them with a machine stall of '
                     + (f'CPU {cpus}' if cpus else 'a CPU') + ' while in flight',
                     f"{len(lt['slow'])}, {sum(hit)}")
        else:
            note('image -> tip force latency (split)', 'no estimate in the run')
        link = r_split.processes.get('link', {})
        sent = sum(c['sent'] for c in link.values())
        lost = sum(c['lost'] for c in link.values())
        for name, c in sorted(link.items()):
            note(f'  link {name}: DDS sent / taken / lost (longest run of lost, at s; '
                 'DDS reported lost)',
                 f"{c['sent']} / {c['taken']} / {c['lost']} ({c.get('longest_run', 0)}, "
                 f"{c.get('run_at_s', 0.0):.2f}; {c.get('dds_reported')})")
        if sent:
            row('lost by DDS on the link topics (target 0) vs injected link loss',
                100.0 * lost / sent, 100.0 * INJECTED_LOSS, ' %', fmt='{:.2f}')
        rec = sum(r_split.recorded.values())
        note('  split: recorded / published (each worker records its own nodes)',
             f'{rec} / {sum(r_split.published.get(t, 0) for t in r_split.recorded)}')
        for name, rep in sorted(r_split.processes.items()):
            if name == 'link':
                continue
            rt = rep.get('realtime', {})
            g = rt.get('gc', {})
            cpus = rep.get('cpus')
            note(f'  {name} process: scheduling, CPUs, GC collections (gen0/1/2), GC total',
                 f"{rt.get('scheduling')}, CPUs {cpus if cpus else 'any'}, "
                 f"{g.get('gen0_count')}/{g.get('gen1_count')}/"
                 f"{g.get('gen2_count')}, {g.get('total_ms', 0):.1f} ms")
        # CPU while the loops ran: each split process against the one process that holds
        # the whole graph (the less noisy figure on a shared machine)
        one_cpu = cpu_share(r_one.realtime)
        for name, rep in sorted(r_split.processes.items()):
            if name == 'link':
                continue
            rt = rep.get('realtime', {})
            row(f'  {name} process CPU while its loop ran, % of a core (ref: the one process)',
                100 * cpu_share(rt), 100 * one_cpu, ' %', fmt='{:.0f}')
            threads = ', '.join(f'{k} {v:.2f}' for k, v in sorted(
                (rt.get('thread_cpu_s') or {}).items(), key=lambda kv: -kv[1])[:3])
            note(f'    {name}: CPU s by thread', threads or '-')
            if rt.get('dds_topics') is not None:
                d = rt['dds_topics']
                note(f'    {name}: published on DDS besides its bus',
                     d if isinstance(d, str) else (', '.join(d) or '-'))
        if load == 'quiet':
            WHERE.append((r_split, r_one, duration))
    row('reference: a lone 1 kHz timer (EventsExecutor), period p99 (quiet)', ref[1], 1.0,
        ' ms', fmt='{:.3f}')


WHERE = []


def where_time_goes():
    """Where a 1 kHz period goes (quiet runs above): per node callback cost, the GC, the
    message work per publish (serialise, deserialise, construct) measured here."""
    for r, how in zip(LOCK, ('vision chain in its own process', 'one process'), strict=False):
        print()
        print(f'lockstep (recorded run above, {how}): wall s inside each node\'s callbacks '
              f'per simulated s (the run: {r.wall_time / r.sim_time:.2f} s per simulated s)')
        for node, c in sorted(r.cost.items(), key=lambda kv: -kv[1]['total_s']):
            print(f"  {node:28s} {c['total_s'] / r.sim_time:6.3f}")
    if not WHERE:
        return
    r_split, r_one, duration = WHERE[0]
    print()
    print('where the time goes (quiet runs above): callback cost per node '
          '(own work, deliveries to it included)')
    print(f"{'node':28s} {'layout':7s} {'calls/s':>8s} {'mean ms':>8s} {'p99 ms':>8s} "
          f"{'max ms':>8s} {'core %':>7s}")
    for layout, r in (('split', r_split), ('one', r_one)):
        for node, c in sorted(r.cost.items()):
            busy = c['total_s'] / c['share'] if c['share'] > 0 else duration   # its loop's time
            print(f"{node:28s} {layout:7s} {c['callbacks'] / busy:8.0f} {c['mean_ms']:8.3f} "
                  f"{c['p99_ms']:8.3f} {c['max_ms']:8.2f} {100 * c['share']:7.1f}")
    per_message()


def per_message():
    """What a message costs the bus: rclpy's (de)serialisation against the bus's encoder and
    snapshot, measured here, each alone."""
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState
    from catheter_bringup.cdr_encode import encoder
    from catheter_bringup.msg_copy import message_copier as copier
    from catheter_interfaces.msg import ImpedanceModel, MasterCommand
    js = JointState(name=['insertion', 'rotation'], position=[0.01, 0.0],
                    velocity=[0.0, 0.0], effort=[0.0, 0.0])
    w = WrenchStamped()
    w.header.frame_id = 'catheter_base'
    im = ImpedanceModel(status='ok', s_table=[0.1] * 20, f_table=[0.1] * 20,
                        b_table=[0.1] * 20, c_table=[0.1] * 20)
    print('per message (us): rclpy serialise / the bus\'s encoder (cdr_encode) / rclpy '
          'deserialise / the bus\'s copy (msg_copy.message_copier) / construct')

    def per_call(fn, n=5000):
        t = time.perf_counter()
        for _ in range(n):
            fn()
        return (time.perf_counter() - t) / n * 1e6
    for name, m in (('JointState', js), ('WrenchStamped', w), ('MasterCommand', MasterCommand()),
                    ('ImpedanceModel', im)):
        b = serialize_message(m)
        enc, cp = encoder(type(m)), copier(type(m))
        ser = per_call(lambda m=m: serialize_message(m))
        en = per_call(lambda m=m, enc=enc: enc(m))
        de = per_call(lambda m=m, b=b: deserialize_message(b, type(m)))
        sn = per_call(lambda m=m, cp=cp: cp(m))
        co = per_call(lambda m=m: type(m)())
        print(f'  {name:14s} {ser:6.1f} / {en:6.1f} / {de:6.1f} / {sn:6.1f} / {co:6.1f}')


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
    from catheter_shape.camera import SYSTEM_CAMERA
    cam = SyntheticCamera(seed=1, **SYSTEM_CAMERA)     # the system camera: shape_node's default
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
        shape = Shape(context=ctx)                    # its default calibration: the system camera
        try:
            est = Est(context=ctx, parameter_overrides=[Parameter('method', value='svr')])
            method = 'svr'
        except Exception:  # noqa: BLE001 - no trained model installed: the FAM inverse
            est = Est(context=ctx, parameter_overrides=[Parameter('method', value='fam')])
            method = 'fam'

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
    row(f'image -> tip force latency p50 (800x800 system camera, {method}, no camera '
        'rendering)', float(np.percentile(lat, 50)),
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
    ap.add_argument('--split-only', action='store_true',
                    help='only part 2 (the split layout beside the one process, quiet and '
                         'loaded) and its callback costs')
    ap.add_argument('--probe', action='store_true',
                    help='the machine stall probe beside the real-time runs (stall_probe: one '
                         'wake-up per ms on each CPU at SCHED_FIFO 99; it perturbs a virtual '
                         'machine: the reference ran 10-20 %% slower with it)')
    ap.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                    help='a scenario override for every real-time run (as run_scenario --set), '
                         'e.g. realtime_cpu_latency_us=0 for runs that hold a CPU latency '
                         'request of 0 us')
    a = ap.parse_args()
    global PROBE
    PROBE = a.probe
    EXTRA_SETS[:] = a.set
    if a.set:
        print('real-time runs with ' + ', '.join(a.set))
    print(f'bench_system on {os.cpu_count()} cores, load average at start '
          f'{os.getloadavg()[0]:.1f} (timings compare within this run)')
    if a.split_only:
        realtime(2.0 if a.quick else 6.0)
        table()
        where_time_goes()
        return
    lockstep(3.0 if a.quick else 12.0, a.quick)
    realtime(2.0 if a.quick else 6.0)
    image_latency(2.0 if a.quick else 5.0)
    recorder_throughput(a.quick)
    for rate in (1000, 5000, 20000):
        recorder_loss(rate, 1.0 if a.quick else 2.0)
    table()
    where_time_goes()


if __name__ == '__main__':
    main()
