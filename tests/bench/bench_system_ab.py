"""The split layout, A/B against another checkout's code in the same session.

    python tests/bench/bench_system_ab.py [--against /path/to/other/checkout] [--rounds 2]
    python tests/bench/bench_system_ab.py --lockstep [--against ...]   # recorded 12 s lockstep
    scripts/bench system_ab

Runs 6 s of real-time Experiment II in the split layout (master, slave, vision processes),
alternating between this checkout and ``--against`` (default: none, this checkout only),
each in a fresh interpreter with that checkout's environment (its scripts/env.sh), and
prints per run: the CPU each worker process used while the loops ran (sampled from
/proc/<pid>/stat every 50 ms, between the runner's "go" and its stop, the first 0.5 s left
out: works for any version of the code, whatever its reports hold), the master's force
loop (rate, period p99), the slave's force stream, and the image -> tip force estimates
(count, latency p99) from the worker reports; `slave` is /slave/force, `imp` and `js` the
period p99 of /slave/impedance and /slave/joint_state. The machine is shared: compare rows of the
same session, alternating, not absolute figures.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: the run, executed inside the checkout's environment; prints one JSON line
CHILD = r'''
import json, os, sys, tempfile, threading, time
from catheter_common.ros_testing import isolate_ros_env
isolate_ros_env()
from catheter_bringup.overrides import apply_overrides
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario
import catheter_bringup.worker as W
dur = float(sys.argv[1])
sc = apply_overrides(load_scenario('experiment_ii'), ['mode=realtime', f'duration={dur}',
                     'link.loss=0.05', 'layout=split'])
sc['record']['only'] = ['/master/rendered_force', '/master/command', '/master/hand_force',
    '/master/dfr/rendered_force', '/slave/force', '/slave/joint_state', '/slave/impedance',
    '/catheter/tip_wrench']
series, marks, stop = {}, {}, []
def sample():
    tck = os.sysconf('SC_CLK_TCK')
    me = str(os.getpid())
    while not stop:
        now = time.monotonic()
        for pid in os.listdir('/proc'):
            if not pid.isdigit():
                continue
            try:
                cmd = open(f'/proc/{pid}/cmdline').read().split('\0')
                if '--process' not in cmd:
                    continue
                f = open(f'/proc/{pid}/stat').read().rsplit(') ', 1)[1].split()
                if f[1] != me:
                    continue
                name = cmd[cmd.index('--process') + 1]
                series.setdefault(name, []).append((now, (int(f[11]) + int(f[12])) / tck))
            except (OSError, ValueError, IndexError):
                pass
        time.sleep(0.05)
_go, _stop = W.Workers.go, W.Workers.stop
def go(self):
    marks['go'] = time.monotonic()
    return _go(self)
def stop_(self, *a, **k):
    marks['stop'] = time.monotonic()
    return _stop(self, *a, **k)
W.Workers.go, W.Workers.stop = go, stop_
threading.Thread(target=sample, daemon=True).start()
with tempfile.TemporaryDirectory() as tmp:
    r = ScenarioRunner(sc, bag=f'{tmp}/ab.mcap', progress=False, log=lambda *a: None).run()
stop.append(1)
def at(ser, t):
    best = None
    for tt, c in ser:
        if tt <= t:
            best = c
    return best
t0, t1 = marks['go'] + 0.5, marks['stop']
cpu = {n: (at(s, t1) - at(s, t0)) / (t1 - t0) for n, s in series.items()
       if at(s, t0) is not None and at(s, t1) is not None}
streams, lat = {}, {}
for k, rep in r.processes.items():
    if k != 'link':
        streams.update(rep.get('realtime', {}).get('streams', {}))
        lat.update(rep.get('realtime', {}).get('latency', {}))
print(json.dumps({'cpu': cpu, 'streams': streams, 'latency': lat,
                  'recorded': sum(r.recorded.values()), 'status': r.status}))
'''


#: lockstep: the recorded 12 s Experiment II, real-time factor and the process's CPU
CHILD_LOCKSTEP = r'''
import json, resource, sys, tempfile, time
from catheter_common.ros_testing import isolate_ros_env
isolate_ros_env()
from catheter_bringup.runner import ScenarioRunner
from catheter_bringup.scenario import load_scenario
sc = load_scenario('experiment_ii')
sc['duration'] = float(sys.argv[1])
with tempfile.TemporaryDirectory() as tmp:
    r = ScenarioRunner(sc, bag=f'{tmp}/ab.mcap', progress=False, log=lambda *a: None)
    r.setup()
    c0 = time.process_time()
    res = r.run()
    cpu = time.process_time() - c0
ch = resource.getrusage(resource.RUSAGE_CHILDREN)
vis = (getattr(res, 'processes', None) or {}).get('vision') or {}
print(json.dumps({'rtf': res.realtime_factor, 'wall': res.wall_time, 'cpu': cpu,
                  'children_cpu': ch.ru_utime + ch.ru_stime,
                  'vision_cpu': vis.get('cpu_total_s') or 0.0,
                  'recorded': sum(res.recorded.values())}))
'''


def run_in(root: pathlib.Path, duration: float, child: str = CHILD) -> dict:
    with tempfile.NamedTemporaryFile('w', suffix='.py', delete=False) as f:
        f.write(child)
        script = f.name
    try:
        cmd = (f'cd {str(root)!r} && . scripts/env.sh >/dev/null && '
               f'PYTHONDONTWRITEBYTECODE=1 python {script} {duration}')
        out = subprocess.run(['bash', '-c', cmd], capture_output=True, text=True, timeout=300)
    finally:
        os.unlink(script)
    for line in reversed(out.stdout.splitlines()):
        if line.startswith('{'):
            return json.loads(line)
    raise RuntimeError(f'no result from {root}: {out.stderr[-1500:]}')


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument('--against', default='', help='another checkout (set up) to compare with')
    ap.add_argument('--rounds', type=int, default=1)
    ap.add_argument('--duration', type=float, default=6.0)
    ap.add_argument('--lockstep', action='store_true',
                    help='the recorded lockstep Experiment II instead (12 s unless --duration)')
    a = ap.parse_args(argv)
    roots = [('this', ROOT)] + ([('other', pathlib.Path(a.against))] if a.against else [])
    if a.lockstep:
        dur = a.duration if a.duration != 6.0 else 12.0
        print(f'lockstep {dur:g} s Exp. II, recorded; load average at start '
              f'{os.getloadavg()[0]:.1f} (compare rows of this session only)')
        print(f"{'code':6s} {'load':>5s} {'rtf':>6s} {'wall s':>7s} {'run CPU s':>9s} "
              f"{'vision CPU s':>12s} {'writer CPU s':>12s} {'recorded':>9s}")
        for _ in range(a.rounds):
            for name, root in roots:
                load = os.getloadavg()[0]
                r = run_in(root, dur, CHILD_LOCKSTEP)
                vis = r.get('vision_cpu', 0.0)     # the lockstep vision process, start-up too
                print(f"{name:6s} {load:5.1f} {r['rtf']:5.2f}x {r['wall']:7.1f} {r['cpu']:9.1f} "
                      f"{vis:12.1f} {r['children_cpu'] - vis:12.1f} {r['recorded']:9d}",
                      flush=True)
        return 0
    print(f'split layout, 6 s Exp. II, 5 % injected link loss; load average at start '
          f'{os.getloadavg()[0]:.1f} (compare rows of this session only)')
    if a.against:
        print(f'  this = {ROOT}, other = {a.against}')
    print(f"{'code':6s} {'load':>5s} {'master %':>8s} {'slave %':>8s} {'vision %':>8s} "
          f"{'rendered Hz':>11s} {'p99 ms':>7s} {'slave Hz':>8s} {'p99 ms':>7s} "
          f"{'imp p99':>7s} {'js p99':>7s} {'estimates':>9s} {'lat p99 ms':>10s}")
    for _ in range(a.rounds):
        for name, root in roots:
            load = os.getloadavg()[0]
            res = run_in(root, a.duration)
            c, s = res['cpu'], res['streams']
            rf = s.get('/master/rendered_force', {})
            sf = s.get('/slave/force', {})
            si, sj = s.get('/slave/impedance', {}), s.get('/slave/joint_state', {})
            lt = res['latency'].get('/catheter/tip_wrench') or {'n': 0, 'p99_ms': float('nan')}
            print(f"{name:6s} {load:5.1f} {100 * c.get('master', float('nan')):8.0f} "
                  f"{100 * c.get('slave', float('nan')):8.0f} "
                  f"{100 * c.get('vision', float('nan')):8.0f} "
                  f"{rf.get('rate_hz', float('nan')):11.1f} {rf.get('p99_ms', float('nan')):7.3f} "
                  f"{sf.get('rate_hz', float('nan')):8.1f} {sf.get('p99_ms', float('nan')):7.3f} "
                  f"{si.get('p99_ms', float('nan')):7.3f} {sj.get('p99_ms', float('nan')):7.3f} "
                  f"{lt['n']:9d} {lt['p99_ms']:10.1f}", flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
