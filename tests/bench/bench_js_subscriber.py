"""What taking a JointState stream through DDS costs the subscribing process: its CPU with the
subscription against the same process without it, by thread (the Python executor thread and
DDS's receive thread), at a given publish rate.

    python tests/bench/bench_js_subscriber.py [--rate 1000] [--seconds 6]

A publisher process (rclpy, a timer at `--rate` publishing sensor_msgs/JointState, QOS_FAST)
and, one after another, subscriber processes (EventsExecutor, a 30 Hz timer doing nothing,
and either a QOS_LATEST subscription whose callback reads position[0] and velocity[0], as
camera_node's, or none), alternating with / without twice; each measures its CPU from /proc
over `--seconds` after 2 s of start-up. Why: the split layout's vision process took the
slave's 1 kHz /slave/joint_state for a 30 Hz camera (round 9, catheter_bringup README).
"""
from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
for _pkg in sorted((ROOT / 'src').iterdir()):
    if (_pkg / 'package.xml').exists() and str(_pkg) not in sys.path:
        sys.path.insert(0, str(_pkg))


def _publisher(rate, stop, domain):
    os.environ['ROS_DOMAIN_ID'] = domain
    import rclpy
    from rclpy.experimental import EventsExecutor
    from sensor_msgs.msg import JointState
    from catheter_common.qos import QOS_FAST
    rclpy.init()
    node = rclpy.create_node('js_publisher')
    pub = node.create_publisher(JointState, '/slave/joint_state', QOS_FAST)
    js = JointState()
    js.name = ['insertion', 'rotation']
    js.position, js.velocity, js.effort = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]

    def tick():
        js.position[0] = time.time() % 1.0
        pub.publish(js)
    node.create_timer(1.0 / rate, tick)
    ex = EventsExecutor()
    ex.add_node(node)
    while not stop.is_set():
        ex.spin_once(0.05)


def _thread_cpu():
    out = {}
    tck = os.sysconf('SC_CLK_TCK')
    for tid in os.listdir('/proc/self/task'):
        try:
            with open(f'/proc/self/task/{tid}/stat') as f:
                s = f.read()
        except OSError:
            continue
        name = s[s.index('(') + 1:s.rindex(')')].rstrip('0123456789.')
        v = s[s.rindex(')') + 2:].split()
        out[name] = out.get(name, 0.0) + (int(v[11]) + int(v[12])) / tck
    return out


def _subscriber(subscribe, seconds, domain, results):
    os.environ['ROS_DOMAIN_ID'] = domain
    import rclpy
    from rclpy.experimental import EventsExecutor
    from sensor_msgs.msg import JointState
    from catheter_common.qos import QOS_LATEST
    rclpy.init()
    node = rclpy.create_node('js_subscriber')
    got = [0]
    state = [0.0, 0.0]

    def on_state(msg):
        state[0], state[1] = msg.position[0], msg.velocity[0]
        got[0] += 1
    if subscribe:
        node.create_subscription(JointState, '/slave/joint_state', on_state, QOS_LATEST)
    node.create_timer(1.0 / 30.0, lambda: None)
    ex = EventsExecutor()
    ex.add_node(node)
    t_end = time.monotonic() + 2.0
    while time.monotonic() < t_end:
        ex.spin_once(0.05)
    c0, th0, w0, n0 = time.process_time(), _thread_cpu(), time.monotonic(), got[0]
    while time.monotonic() < w0 + seconds:
        ex.spin_once(0.05)
    wall = time.monotonic() - w0
    cpu = time.process_time() - c0
    th = _thread_cpu()
    threads = {k: 100.0 * (th[k] - th0.get(k, 0.0)) / wall for k in th}
    results.put((subscribe, got[0] - n0, wall, 100.0 * cpu / wall, threads))
    ex.shutdown()
    node.destroy_node()
    rclpy.shutdown()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--rate', type=float, default=1000.0)
    ap.add_argument('--seconds', type=float, default=6.0)
    a = ap.parse_args()
    from catheter_common.ros_testing import isolate_ros_env
    domain = str(isolate_ros_env())
    ctx = mp.get_context('spawn')
    stop, results = ctx.Event(), ctx.Queue()
    pub = ctx.Process(target=_publisher, args=(a.rate, stop, domain))
    pub.start()
    print(f'bench_js_subscriber: JointState at {a.rate:g} Hz, {a.seconds:g} s per run, load '
          f'average {os.getloadavg()[0]:.1f}')
    try:
        for subscribe in (True, False, True, False):
            p = ctx.Process(target=_subscriber, args=(subscribe, a.seconds, domain, results))
            p.start()
            sub, n, wall, cpu, threads = results.get(timeout=60)
            p.join()
            top = ', '.join(f'{k} {v:.1f}' for k, v in sorted(threads.items(),
                                                               key=lambda kv: -kv[1]) if v >= 0.05)
            print(f'  subscribed {str(sub):5s}: {n:6d} messages in {wall:.1f} s, process CPU '
                  f'{cpu:5.1f} % of a core (by thread, %: {top})')
    finally:
        stop.set()
        pub.join()


if __name__ == '__main__':
    main()
