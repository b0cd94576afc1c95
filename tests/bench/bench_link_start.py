"""The split layout's link, reduced to one stream: two processes like the slave (a 1 kHz
WrenchStamped publisher, QOS_FAST, header stamps on the wall clock) and the master (a QOS_FAST
subscription on an EventsExecutor), started the way `worker.Workers` starts the workers: both
loops begin when both nodes are in the ROS graph (a "go" file). Per repetition: when each side
saw the other matched, when the publisher's get_subscription_count() first said > 0 (what
sim_slave_node checks before it publishes), what was sent before the subscriber's first
sample, what `realtime.link_loss` counts inside its window, and what DDS itself reported lost
(the subscription's message_lost event: a sequence gap seen by the reader).

    python tests/bench/bench_link_start.py [--reps 10] [--dur 2] [--stall S | --freeze S]

--stall S: the subscriber's executor blocked S s (a callback that sleeps) 0.8 s into the run -
what a master whose executor stops taking looks like. --freeze S: the subscriber process
stopped (SIGSTOP) S s 0.8 s into the run - its DDS threads too. Issue 15: which of these can
give the once-seen 317-sample /slave/force loss, and whether the start of the window can."""
from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time

TOPIC = '/bench_link/force'


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def role_pub(go: str, dur: float, out: str) -> None:
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.event_handler import PublisherEventCallbacks
    from rclpy.experimental import EventsExecutor

    from catheter_common.qos import QOS_FAST
    rclpy.init()
    node = rclpy.create_node('bench_link_slave')
    ev = {}
    cbs = PublisherEventCallbacks(matched=lambda _s: ev.setdefault('matched_ns', time.time_ns()))
    pub = node.create_publisher(WrenchStamped, TOPIC, QOS_FAST, event_callbacks=cbs)
    exe = EventsExecutor()
    exe.add_node(node)
    while not os.path.exists(go):
        exe.spin_once(timeout_sec=0.005)
    sent, msg = [], WrenchStamped()

    def tick():
        ns = time.time_ns()
        if 'count_ns' not in ev and pub.get_subscription_count() > 0:
            ev['count_ns'] = ns
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        pub.publish(msg)
        sent.append(ns)
    go_ns = time.time_ns()
    node.create_timer(0.001, tick)
    end = time.monotonic() + dur
    while time.monotonic() < end:
        exe.spin_once(timeout_sec=0.01)
    with open(out, 'w') as f:
        json.dump(dict(go_ns=go_ns, sent=sent, **ev), f)


def role_sub(go: str, dur: float, out: str, stall: float) -> None:
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.experimental import EventsExecutor

    from catheter_common.qos import QOS_FAST
    rclpy.init()
    node = rclpy.create_node('bench_link_master')
    ev = {'dds_lost': 0}

    def lost(status):
        ev['dds_lost'] = status.total_count
    cbs = SubscriptionEventCallbacks(
        matched=lambda _s: ev.setdefault('matched_ns', time.time_ns()), message_lost=lost)
    taken = []
    node.create_subscription(WrenchStamped, TOPIC, lambda m: taken.append(_ns(m.header.stamp)),
                             QOS_FAST, event_callbacks=cbs)
    exe = EventsExecutor()
    exe.add_node(node)
    while not os.path.exists(go):
        exe.spin_once(timeout_sec=0.005)
    go_ns = time.time_ns()
    if stall > 0:
        done = []

        def block():
            if not done:
                done.append(1)
                time.sleep(stall)
        node.create_timer(0.8, block)
    end = time.monotonic() + dur + 0.2
    while time.monotonic() < end:
        exe.spin_once(timeout_sec=0.01)
    with open(out, 'w') as f:
        json.dump(dict(go_ns=go_ns, taken=taken, **ev), f)


def repetition(r: int, tmp: str, a, probe) -> dict:
    import rclpy

    from catheter_bringup.realtime import link_loss
    go = f'{tmp}/go_{r}'
    files = {k: f'{tmp}/{k}_{r}.json' for k in ('pub', 'sub')}
    me = [sys.executable, os.path.abspath(__file__)]
    procs = [subprocess.Popen(me + ['pub', go, str(a.dur), files['pub']]),
             subprocess.Popen(me + ['sub', go, str(a.dur), files['sub'], str(a.stall)])]
    t0 = time.monotonic()
    while {'bench_link_slave', 'bench_link_master'} - set(probe.get_node_names()):
        rclpy.spin_once(probe, timeout_sec=0.02)
        if time.monotonic() - t0 > 60:
            raise RuntimeError('the two processes were not in the graph within 60 s')
    graph_s = time.monotonic() - t0
    open(go, 'w').close()
    if a.freeze > 0:
        time.sleep(0.8)
        procs[1].send_signal(signal.SIGSTOP)
        time.sleep(a.freeze)
        procs[1].send_signal(signal.SIGCONT)
    for p in procs:
        if p.wait(timeout=120) != 0:
            raise RuntimeError(f'a role process exited {p.returncode}')
    with open(files['pub']) as f:
        pub = json.load(f)
    with open(files['sub']) as f:
        sub = json.load(f)
    go_ns = min(pub['go_ns'], sub['go_ns'])

    def ms(d, k):
        return None if d.get(k) is None else (d[k] - go_ns) * 1e-6
    first_taken = min(sub['taken']) if sub['taken'] else None
    ll = link_loss(pub['sent'], sub['taken'])
    return dict(rep=r, graph_s=graph_s, pub_matched_ms=ms(pub, 'matched_ns'),
                sub_matched_ms=ms(sub, 'matched_ns'), count_ms=ms(pub, 'count_ns'),
                first_taken_ms=None if first_taken is None else (first_taken - go_ns) * 1e-6,
                before_first=sum(1 for s in pub['sent'] if first_taken and s < first_taken),
                window_sent=ll['sent'], window_lost=ll['lost'], longest=ll['longest_run'],
                run_at_s=ll['run_at_s'], dds_lost=sub['dds_lost'])


def main(argv=None) -> int:
    if argv is None and len(sys.argv) > 1 and sys.argv[1] in ('pub', 'sub'):
        if sys.argv[1] == 'pub':
            role_pub(sys.argv[2], float(sys.argv[3]), sys.argv[4])
        else:
            role_sub(sys.argv[2], float(sys.argv[3]), sys.argv[4], float(sys.argv[5]))
        return 0
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--reps', type=int, default=10)
    ap.add_argument('--dur', type=float, default=2.0, help='s of publishing per repetition')
    ap.add_argument('--stall', type=float, default=0.0, metavar='S')
    ap.add_argument('--freeze', type=float, default=0.0, metavar='S')
    a = ap.parse_args(argv)
    if a.stall and a.freeze:
        ap.error('--stall and --freeze are separate experiments')
    import rclpy

    from catheter_common.ros_testing import isolate_ros_env
    isolate_ros_env()
    rclpy.init()
    probe = rclpy.create_node('bench_link_probe')
    print(f'load average at start: {os.getloadavg()[0]:.2f}')
    hdr = ('rep', 'graph s', 'pub matched ms', 'sub matched ms', 'count>0 ms',
           'first taken ms', 'sent before it', 'window sent', 'window lost', 'longest run',
           'at s', 'DDS lost')
    print(' | '.join(hdr))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.reps):
            x = repetition(r, tmp, a, probe)
            rows.append(x)
            print(' | '.join('-' if v is None else (f'{v:.1f}' if isinstance(v, float) else str(v))
                             for v in x.values()), flush=True)
    probe.destroy_node()
    rclpy.try_shutdown()
    late = [x for x in rows if x['sub_matched_ms'] is not None and x['sub_matched_ms'] > 0]
    print(f'\n{a.reps} repetitions (load average now {os.getloadavg()[0]:.2f}): the subscriber '
          f'matched after the go in {len(late)}; samples sent before the first taken '
          f'median {statistics.median(x["before_first"] for x in rows):g}, max '
          f'{max(x["before_first"] for x in rows)} (outside link_loss\'s window); lost inside '
          f'the window: {sum(x["window_lost"] for x in rows)} of '
          f'{sum(x["window_sent"] for x in rows)}, longest run '
          f'{max(x["longest"] for x in rows)}; DDS reported lost '
          f'{sum(x["dds_lost"] for x in rows)}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
