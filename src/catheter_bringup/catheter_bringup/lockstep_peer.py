"""Lockstep with the vision chain in a process of its own: the main process's side (no rclpy).

In Experiment II (``force_source: load_cell``) the vision chain (camera -> shape -> force
estimator, 30 Hz) is a pure observer: nothing of the 1 kHz loop consumes what it publishes.
So it can run in lockstep in a second process, pipelined behind the main one, on the other
core, and the run still records the SAME messages with the SAME log times in the SAME order
as the one-process run:

- **Order.** In one process, a lockstep step runs every due timer in a fixed order (nodes
  in start order, timers in creation order; `Stepping._drain_bus`) and the recorder takes
  each timer's messages, and what their deliveries publish, in publish order before the
  next timer runs. Every message therefore has a key: (step, pass, node index, timer
  index) of the timer whose callback started its cascade, then its place in the cascade.
  Both processes know the global node order, so each tags what it records with that key,
  and merging the two streams by key (stable) gives the one-process order exactly, as
  long as no cascade crosses the processes.
- **Inputs.** What the vision nodes subscribe to that the main process publishes (the
  slave's joint state for the camera) is forwarded with its key; the vision process
  delivers it between its own timers at the same place in the step
  (`catheter_bringup.lockstep_follower`). A vision node that publishes while taking such an
  input would start a cascade across the processes: the follower refuses it (the run
  fails, saying so; ``lockstep_processes: 1`` runs it in one process).
- **Pipelined.** The main process never waits for vision during the run: it hands over the
  inputs every `FLUSH_STEPS` steps with a watermark ("steps up to k are complete"), keeps
  what it recorded until the vision process has reported the same steps done, and writes
  the merged stream to the recording. At the end it waits for the vision process to catch
  up (`VisionPeer.finish`: the wait is in the run's wall time and in its report).

When the 1 kHz nodes DO consume the vision chain (``force_source: image``: the identifier
fits the image-based force), or a scenario says ``lockstep_processes: 1``, or the run
replays recorded inputs (reprocess), everything stays in one process (`vision_plan`).

Frames (both directions): ``<BIHHHHI`` (kind, step, pass, node index, timer index, topic
id, payload length) + payload. Pass 0 = before the drain's first timer, `PASS_SPIN` = the
executor spin after the timers.
"""
from __future__ import annotations

import collections
import heapq
import json
import os
import select
import struct
import subprocess
import sys
import tempfile
import time
from typing import Callable, Dict, List, Optional

FRAME = struct.Struct('<BIHHHHI')
MSG, STEP, END, TOPIC, READY, REPORT, ERROR = 1, 2, 3, 4, 5, 6, 7
#: the pass of a message published in the executor spin after a drain's timers
PASS_SPIN = 0xFFFF
#: steps between two hand-overs of the main process's inputs and watermark (and reads of
#: what the vision process sent back)
FLUSH_STEPS = 16
#: bytes asked for each pipe (Linux F_SETPIPE_SZ; the default is 64 kB, an 800x800 frame
#: is 640 kB)
PIPE_BYTES = 1 << 20
_F_SETPIPE_SZ = 1031
#: s, the longest the vision process may take to start (imports, node construction)
READY_TIMEOUT = 180.0
#: s without any progress of the vision process at the end before it is killed
STALL_TIMEOUT = 60.0


def _topic_of(entry):
    return entry[2]


def _key_of(entry):
    return entry[1]


class VisionError(RuntimeError):
    """The vision process failed (a node raised, it refused a crossing cascade, it died)."""


def vision_plan(scenario, chosen, inject=None) -> list:
    """The node instances of `chosen` to run in a lockstep vision process (empty: run all in
    one process). Only in lockstep on the local bus, with ``lockstep_processes`` >= 2,
    without injected inputs (reprocess), when there are vision nodes (`NodeSpec.kind`) and
    other nodes, and no other node consumes what a vision node produces."""
    if scenario.get('mode') != 'lockstep' or int(scenario.get('lockstep_processes', 2)) < 2:
        return []
    if scenario.get('lockstep_transport', 'local') != 'local' or inject is not None:
        return []
    vis = [i for i in chosen if i.spec.kind == 'vision']
    rest = [i for i in chosen if i.spec.kind != 'vision']
    if not vis or not rest:
        return []
    produced = {t for i in vis for t in i.spec.produces}
    if any(t in produced for i in rest for t in i.spec.consumes):
        return []
    return vis


def frame(kind: int, step: int = 0, key=(0, 0, 0), tid: int = 0, body: bytes = b'') -> bytes:
    return FRAME.pack(kind, step, key[0], key[1], key[2], tid, len(body)) + body


def parse_frames(buf: bytearray):
    """Complete frames at the start of `buf` as (kind, step, key, topic id, payload bytes);
    removes them from `buf`."""
    out = []
    off = 0
    n = len(buf)
    size = FRAME.size
    unpack = FRAME.unpack_from
    view = memoryview(buf)
    try:
        while n - off >= size:
            kind, step, p, node, tmr, tid, length = unpack(buf, off)
            if n - off - size < length:
                break
            start = off + size
            out.append((kind, step, (p, node, tmr), tid, bytes(view[start:start + length])))
            off = start + length
    finally:
        view.release()
    if off:
        del buf[:off]
    return out


def set_pipe_size(fd: int) -> None:
    try:
        import fcntl
        fcntl.fcntl(fd, _F_SETPIPE_SZ, PIPE_BYTES)
    except OSError:
        pass                            # the default size: the buffers absorb the rest


class VisionPeer:
    """The vision process of a lockstep run, seen from the main process.

    ``VisionPeer(plan, log)`` starts it (``python -m catheter_bringup.lockstep_follower``)
    with the plan (scenario, registry, global node order, its nodes, whether and what to
    record); `wait_ready` takes its start report; `attach(runner, recorder, received)`
    makes it the recorder of the runner's sink (`write`: what the main process records,
    kept until merged) and `forward` the bus's hook for the inputs; `step_done(k)` after
    each step; `finish(last_step)` at the end (waits for the vision process, merges the
    rest, takes its report); `kill` when the run is abandoned."""

    def __init__(self, plan: dict, log: Callable[[str], None] = print,
                 python: str = sys.executable):
        self.log = log
        self.nodes: List[str] = list(plan['nodes'])
        self.error: Optional[str] = None
        self.report: Optional[dict] = None
        self.ready: Optional[dict] = None
        #: s the main process waited for the vision process at the end of the run
        self.wait_s = 0.0
        fd, self._plan = tempfile.mkstemp(suffix='.json', prefix='lockstep_vision_')
        with os.fdopen(fd, 'w') as f:
            json.dump(plan, f)
        self._stderr = tempfile.TemporaryFile(mode='w+b')
        # a session of its own, hence (with kernel.sched_autogroup_enabled, most kernels'
        # setting) a CPU share of its own: CFS shares the CPU between sessions first, so in
        # the main process's session the two processes together got one share of a busy
        # machine (measured: the split run slower than one process under load). Its life
        # is its pipes, not the terminal's signals (`lockstep_follower`)
        self.proc = subprocess.Popen(
            [python, '-m', 'catheter_bringup.lockstep_follower', self._plan],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr,
            start_new_session=True)
        self._wfd = self.proc.stdin.fileno()
        self._rfd = self.proc.stdout.fileno()
        set_pipe_size(self._wfd)
        set_pipe_size(self._rfd)
        os.set_blocking(self._wfd, False)
        os.set_blocking(self._rfd, False)
        self._out = bytearray()
        self._in = bytearray()
        self._eof = False
        self._inputs: Dict[str, int] = {}
        self._topics: Dict[int, str] = {}
        self._main = collections.deque()   # (step, key, topic, data, log time)
        self._vis = collections.deque()    # (step, key, topic, data, log time)
        self._done = -1                    # the last step the vision process finished
        self.runner = None
        self.recorder = None
        self.received: Optional[Dict[str, int]] = None
        self._dt_ns = int(round(float(plan['scenario']['step']) * 1e9))
        log(f'[run] vision process (pid {self.proc.pid}), lockstep: {", ".join(self.nodes)}')

    # ------------------------------------------------------------------ start
    def wait_ready(self, timeout: float = READY_TIMEOUT) -> dict:
        """The vision process's start report (its nodes, the ones left out, its inputs and
        recorded topics); VisionError if it failed or did not start in `timeout` s."""
        t_end = time.monotonic() + timeout
        while self.ready is None:
            left = t_end - time.monotonic()
            if left <= 0:
                self.kill()
                raise VisionError(f'the vision process did not start in {timeout:g} s: '
                                  f'{self.stderr_tail()}')
            select.select([self._rfd], [], [], min(left, 0.5))
            self._read()
            for kind, _step, _key, _tid, body in parse_frames(self._in):
                if kind == READY:
                    self.ready = json.loads(body)
                elif kind == ERROR:
                    self.error = json.loads(body).get('reason', '?')
                    self.kill()
                    raise VisionError(f'the vision process failed to start: {self.error}')
            if self.ready is None and self._eof:
                self.kill()
                raise VisionError('the vision process ended before it started (exit code '
                                  f'{self.proc.returncode}): {self.stderr_tail()}')
        self._inputs = {t: k for k, t in enumerate(self.ready['inputs'])}
        return self.ready

    def attach(self, runner, recorder, received: Optional[Dict[str, int]]) -> None:
        """Take over the runner's recording (`recorder`: the real one; `received`: the
        sink's per-topic counts, which get the vision topics) and register the topics the
        vision process records."""
        self.runner = runner
        self.recorder = recorder
        self.received = received
        if recorder is not None:
            for k, t in enumerate(self.ready['topics']):
                recorder.add_topic(t['topic'], t['type'], t['qos'])
                self._topics[k] = t['topic']
                if received is not None:
                    received[t['topic']] = 0

    # ------------------------------------------------------------------ the run
    def forward(self, topic: str, data: bytes) -> None:
        """The bus's hook for every publish of the main process: an input of the vision
        process goes to it, tagged with the step and the key of its cascade."""
        tid = self._inputs.get(topic)
        if tid is not None:
            r = self.runner
            self._out += FRAME.pack(MSG, r._step, *r._key, tid, len(data))
            self._out += data

    # the recorder interface of the runner's sink (RecordingSink calls add_topic and write)
    def add_topic(self, topic, type_name, qos=None):
        return self.recorder.add_topic(topic, type_name, qos)

    def write(self, topic: str, data: bytes, log_time_ns: int) -> None:
        r = self.runner
        self._main.append((r._step, r._key, topic, data, log_time_ns))

    def step_done(self, k: int) -> None:
        """After the main process's step k: every `FLUSH_STEPS` steps hand over the inputs
        and the watermark, take what the vision process sent, write what is merged."""
        if k % FLUSH_STEPS:
            return
        self._out += FRAME.pack(STEP, k, 0, 0, 0, 0, 0)
        self._write()
        self._pump()

    def _write(self) -> None:
        if not self._out:
            return
        try:
            n = os.write(self._wfd, self._out)
        except BlockingIOError:
            return
        except BrokenPipeError:
            self._eof = True
            raise VisionError(self._died()) from None
        del self._out[:n]

    def _read(self) -> int:
        got = 0
        while True:
            try:
                b = os.read(self._rfd, PIPE_BYTES)
            except BlockingIOError:
                return got
            if not b:
                self._eof = True
                return got
            self._in += b
            got += len(b)

    def _pump(self) -> None:
        """Take what the vision process sent; write what both processes have finished."""
        self._read()
        self._take(parse_frames(self._in))
        if self.error is not None:
            raise VisionError(f'vision process: {self.error}')
        if self._eof and self.report is None:
            raise VisionError(self._died())
        self._merge(self._done)

    def _take(self, frames) -> None:
        vis = self._vis
        received = self.received
        for kind, step, key, tid, body in frames:
            if kind == MSG:
                topic = self._topics[tid]
                vis.append((step, key, topic, body, step * self._dt_ns))
                if received is not None:
                    received[topic] += 1
            elif kind == STEP:
                self._done = step
            elif kind == REPORT:
                self.report = json.loads(body)
                if self.report.get('status') == 'failed':
                    self.error = self.report.get('reason') or 'failed'
            elif kind == ERROR:
                self.error = json.loads(body).get('reason', '?')

    def _merge(self, upto: Optional[int]) -> None:
        """Write the recorded messages of both processes up to step `upto` (None: all), each
        step as the one-process run's sink writes it: merged in cascade-key order (keys
        never tie across the processes: a timer belongs to one), then grouped by topic
        (a stable sort: `RecordingSink.flush`)."""
        main, vis = self._main, self._vis
        write = self.recorder.write if self.recorder is not None else None
        by_topic = _topic_of
        while main or vis:
            k = min(main[0][0] if main else 2 ** 62, vis[0][0] if vis else 2 ** 62)
            if upto is not None and k > upto:
                return
            batch = []
            while main and main[0][0] == k:
                batch.append(main.popleft())
            if vis and vis[0][0] == k:
                theirs = []
                while vis and vis[0][0] == k:
                    theirs.append(vis.popleft())
                batch = list(heapq.merge(batch, theirs, key=_key_of))
            if write is None:
                continue
            batch.sort(key=by_topic)
            for _k, _key, topic, data, t in batch:
                write(topic, data, t)

    # ------------------------------------------------------------------ the end
    def finish(self, last_step: int, status: str = 'complete') -> Optional[dict]:
        """End the vision process after step `last_step` (the last one the main process
        completed): it runs every step up to there, sends the rest and its report, and
        exits; everything is merged into the recording. Returns its report (None if none
        came); `error` says why it failed. A vision process that makes no progress for
        `STALL_TIMEOUT` s is killed."""
        t0 = time.perf_counter()
        if not self._eof:
            self._out += FRAME.pack(STEP, max(last_step, 0), 0, 0, 0, 0, 0) \
                if last_step >= 0 else b''
            self._out += frame(END, body=json.dumps({'last_step': last_step,
                                                     'status': status}).encode())
        last_progress = time.monotonic()
        while self.report is None and not self._eof:
            ws = [self._wfd] if self._out else []
            r, w, _ = select.select([self._rfd], ws, [], 0.5)
            if w:
                try:
                    self._write()
                except VisionError:
                    break
            if r and self._read():
                last_progress = time.monotonic()
                self._take(parse_frames(self._in))
                self._merge(self._done)
            if time.monotonic() - last_progress > STALL_TIMEOUT:
                self.error = (f'no progress for {STALL_TIMEOUT:g} s at the end of the run '
                              f'(last step done: {self._done}): killed')
                break
        self._take(parse_frames(self._in))
        if self.report is None and self.error is None:
            self.error = self._died()
        self._merge(None)
        self.wait_s = time.perf_counter() - t0
        self._close_process()
        return self.report

    def _died(self) -> str:
        try:
            code = self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            code = None
        return (f'the vision process ended unexpectedly (exit code {code}): '
                f'{self.stderr_tail()}')

    def stderr_tail(self, n: int = 1500) -> str:
        try:
            self._stderr.seek(0)
            text = self._stderr.read().decode(errors='replace')
        except (OSError, ValueError):
            return ''
        return text[-n:].strip()

    def _close_process(self) -> None:
        for f in (self.proc.stdin, self.proc.stdout):
            try:
                f.close()
            except OSError:
                pass
        try:
            self.proc.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self.log('[run] the vision process did not exit: killed')
            self.proc.kill()
            self.proc.wait()
        try:
            os.unlink(self._plan)
        except OSError:
            pass

    def kill(self) -> None:
        """Abandon the vision process (a run that ends before it started)."""
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self._close_process()

    @property
    def running(self) -> bool:
        return self.proc.poll() is None
