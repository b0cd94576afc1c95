"""Stress: the node executables (ros_ws/install/<pkg>/lib/<pkg>/<exe>) started as processes and
stopped by SIGINT or SIGTERM at random moments, many times; every node must exit 0 within
--timeout s of its signal, without a traceback (issue 15).

    python tests/bench/stress_node_signals.py [-n 40] [--nodes all|a,b] [--ignore-sigint]
        [--after-running S | --tmin S --tmax S] [--together P] [--load N] [--timeout S]

Each iteration starts the nodes at once (the whole graph by default, under /robot1, as
tests/nodes/test_processes.py does), then signals each at a moment drawn from [tmin, tmax] s
after the start (the same moment for all with probability --together), or, with
--after-running S, from [0, S] s after its "running" log line. --ignore-sigint starts them
with SIGINT ignored, as a background job of a shell without job control or nohup does.
--load N adds N busy-loop processes (nice 5). A node still running --timeout s after its
signal is diagnosed (CPU it used in 2 s, signal masks, py-spy stacks with locals if py-spy is
installed, gdb backtraces if gdb is), then killed; its log and the diagnosis stay in --out.
Prints one line per iteration and a summary. Not a test: minutes of CPU on every core."""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import random
import shutil
import signal
import subprocess
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / 'tests' / 'nodes'))
from node_cases import NODE_PACKAGES  # noqa: E402

EXECUTABLES = dict(NODE_PACKAGES, recorder_node='catheter_bringup')


def executable(name: str) -> str:
    pkg = EXECUTABLES[name]
    return str(ROOT / 'ros_ws' / 'install' / pkg / 'lib' / pkg / name)


def diagnose(pid: int, path: pathlib.Path) -> None:
    """What a process that did not stop is doing: CPU over 2 s, signal masks, stacks."""
    out = []

    def ticks():
        f = open(f'/proc/{pid}/stat').read().rsplit(')', 1)[1].split()
        return int(f[11]) + int(f[12])
    c0 = ticks()
    time.sleep(2.0)
    out.append(f'CPU ticks in 2 s: {ticks() - c0}')
    out.append(''.join(line for line in open(f'/proc/{pid}/status')
                       if line.startswith(('Sig', 'Shd'))))
    cmds = []
    if shutil.which('py-spy'):
        cmds.append(['py-spy', 'dump', '--locals', '--pid', str(pid)])
    if shutil.which('gdb'):
        cmds.append(['gdb', '-p', str(pid), '-batch', '-ex', 'thread apply all bt 25'])
    for cmd in cmds:
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=90)
            out.append(' '.join(cmd[:2]) + '\n' + r.stdout + r.stderr)
        except (OSError, subprocess.TimeoutExpired) as exc:
            out.append(f'{cmd[0]}: {exc}')
    path.write_text('\n'.join(out))


def one_iteration(i, a, names, rnd, out):
    sig = rnd.choice([signal.SIGINT, signal.SIGTERM])
    together = rnd.random() < a.together
    from catheter_common.ros_testing import isolated_domain
    env = dict(os.environ, ROS_DOMAIN_ID=str(isolated_domain(os.getpid() + i)),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    old = signal.signal(signal.SIGINT, signal.SIG_IGN) if a.ignore_sigint else None
    procs, logs, at = {}, {}, {}
    d0 = rnd.uniform(a.tmin, a.tmax)
    t0 = time.monotonic()
    try:
        for n in names:
            args = ['--ros-args', '-r', '__ns:=/robot1']
            if n == 'recorder_node':
                args += ['-p', f'path:={out}/rec_{i}.mcap']
            logs[n] = out / f'{i}_{n}.log'
            with open(logs[n], 'wb') as f:
                procs[n] = subprocess.Popen([executable(n)] + args, stdout=f,
                                            stderr=subprocess.STDOUT, env=env)
            at[n] = None if a.after_running is not None else \
                (d0 if together else rnd.uniform(a.tmin, a.tmax))
    finally:
        if old is not None:
            signal.signal(signal.SIGINT, old)
    sent, res = {}, {}
    while len(res) < len(names):
        now = time.monotonic() - t0
        for n in names:
            p = procs[n]
            if n in res:
                continue
            if n not in sent:
                if p.poll() is not None:            # exited before its signal
                    res[n] = (p.returncode, None)
                    continue
                if at[n] is None and b'running;' in logs[n].read_bytes():
                    at[n] = now + rnd.uniform(0.0, a.after_running)
                if at[n] is not None and now >= at[n]:
                    p.send_signal(sig)
                    sent[n] = time.monotonic()
                continue
            if p.poll() is not None:
                res[n] = (p.returncode, time.monotonic() - sent[n])
            elif time.monotonic() - sent[n] > a.timeout:
                diagnose(p.pid, out / f'{i}_{n}.hang')
                p.kill()
                p.wait()
                res[n] = ('HANG', None)
        time.sleep(0.005)
    rows = []
    for n in names:
        code, dt = res[n]
        text = logs[n].read_text(errors='replace')
        ok = code == 0 and dt is not None and 'Traceback' not in text and 'FATAL' not in text
        rows.append(dict(i=i, node=n, sig=sig.name, at=None if at[n] is None else round(at[n], 3),
                         code=code, exit_s=None if dt is None else round(dt, 3), ok=ok))
        if ok:
            logs[n].unlink()
    return rows, together


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('-n', type=int, default=20, help='iterations')
    ap.add_argument('--nodes', default='all', help='all, or executables separated by commas')
    ap.add_argument('--tmin', type=float, default=0.0)
    ap.add_argument('--tmax', type=float, default=6.0)
    ap.add_argument('--after-running', type=float, default=None, metavar='S')
    ap.add_argument('--together', type=float, default=0.5)
    ap.add_argument('--ignore-sigint', action='store_true')
    ap.add_argument('--load', type=int, default=0, help='busy-loop processes (nice 5)')
    ap.add_argument('--timeout', type=float, default=30.0)
    ap.add_argument('--seed', type=int, default=1)
    ap.add_argument('--out', default='out/stress_node_signals')
    a = ap.parse_args(argv)
    names = list(EXECUTABLES) if a.nodes == 'all' else a.nodes.split(',')
    unknown = sorted(set(names) - set(EXECUTABLES))
    if unknown:
        ap.error(f'unknown executables {unknown}; known: {sorted(EXECUTABLES)}')
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rnd = random.Random(a.seed)
    load = [subprocess.Popen(['nice', '-n', '5', sys.executable, '-c', 'while True: pass'])
            for _ in range(a.load)]
    rows = []
    t_start = time.monotonic()
    try:
        for i in range(a.n):
            r, together = one_iteration(i, a, names, rnd, out)
            rows += r
            bad = [x for x in r if not x['ok']]
            worst = max((x['exit_s'] for x in r if x['exit_s'] is not None), default=0.0)
            print(f'iter {i}: {r[0]["sig"]}, together={together}, slowest exit {worst:.2f} s, '
                  f'bad {len(bad)}', flush=True)
            for x in bad:
                print('   ', json.dumps(x), flush=True)
    finally:
        for p in load:
            p.kill()
            p.wait()
    exits = sorted(x['exit_s'] for x in rows if x['exit_s'] is not None)
    hangs = sum(1 for x in rows if x['code'] == 'HANG')
    bad = sum(1 for x in rows if not x['ok'])
    p50 = exits[len(exits) // 2] if exits else float('nan')
    print(f'\n{len(rows)} node runs in {a.n} iterations, {time.monotonic() - t_start:.0f} s: '
          f'{len(rows) - bad} clean, {hangs} still running {a.timeout:g} s after the signal, '
          f'{bad - hangs} other failures; exit after the signal p50 {p50:.2f} s, '
          f'max {exits[-1] if exits else float("nan"):.2f} s')
    (out / 'summary.json').write_text(json.dumps(rows, indent=1))
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
