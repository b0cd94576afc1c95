"""A worker's recording written by a process of its own (no rclpy).

In layout split every worker records what its nodes publish (`local_recording`). Writing the
part file inside the worker (the exact-length walk, mcap's record packing, zstd on every
64 kB chunk) cost the 1 kHz processes a sixth of a core in the master and a tenth in the
slave (measured: master 96 % of a core recording, 79 % not; slave 67 % / 58 %), at real-time
priority, ahead of the vision process. `PartPipe` keeps only the cheap part in the worker:
each publish's CDR bytes are appended to a buffer with a 15-byte frame header, and the
buffer goes to a writer process through a pipe (non-blocking: a writer that falls behind
never stalls the loop; what the pipe does not take waits in the buffer). The writer
(``python -m catheter_bringup.part_pipe PATH PROCESS``, normal scheduling, started before
the worker's loop takes real-time priority) unpacks the frames into a `PartRecorder`.

Frames: ``<BHqI`` (kind, topic id, log time ns, payload length) + payload; kinds: TOPIC
(payload: JSON {topic, type, qos}), MESSAGE (payload: CDR bytes), CLOSE (payload: JSON
{status, reason}). At the end the writer closes the part and prints its counts as one JSON
line. A worker killed with SIGKILL closes the pipe by dying: the writer takes every frame
that reached the pipe and closes the part as ``interrupted`` (lost: at most the frames
still in the worker's buffer, `FLUSH_BYTES`).
"""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import time
from typing import Dict, List, Mapping, Optional

FRAME = struct.Struct('<BHqI')
TOPIC, MESSAGE, CLOSE = 1, 2, 3
#: bytes: the worker hands its buffer to the pipe once it holds this much (and at `flush`)
FLUSH_BYTES = 8 * 1024
#: bytes asked for the pipe (Linux F_SETPIPE_SZ; the default is 64 kB): about 0.15 s of a
#: master process's messages while the writer is not scheduled
PIPE_BYTES = 1 << 20
_F_SETPIPE_SZ = 1031


class PartPipe:
    """The worker's side: `add_topic`, `record(topic, cdr_bytes)` from the bus (topics not
    added are ignored), `flush` now and then, `close` at the end (waits for the writer and
    takes its counts). The interface of `local_recording.PartRecorder`."""

    def __init__(self, path, process: str, python: str = sys.executable):
        self.path = str(path)
        self.topics: Dict[str, int] = {}
        self.errors = 0
        self.closed = False
        self.sent: Dict[str, int] = {}
        self._counts: Optional[Dict[str, int]] = None
        self._buf = bytearray()
        self._clock = time.time_ns     # the system clock: what the nodes' clocks use
        self.proc = subprocess.Popen([python, '-m', 'catheter_bringup.part_pipe', self.path,
                                      process], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE)
        self._fd = self.proc.stdin.fileno()
        try:
            import fcntl
            fcntl.fcntl(self._fd, _F_SETPIPE_SZ, PIPE_BYTES)
        except OSError:
            pass                       # the default pipe size: the buffer absorbs the rest
        os.set_blocking(self._fd, False)

    @property
    def counts(self) -> Dict[str, int]:
        """What the writer recorded per topic (after `close`; before: what was handed over)."""
        return dict(self._counts if self._counts is not None else self.sent)

    def add_topic(self, topic: str, type_name: str, qos: Optional[List[Mapping]]) -> None:
        if topic in self.topics:
            return
        tid = self.topics[topic] = len(self.topics)
        self.sent[topic] = 0
        body = json.dumps({'topic': topic, 'type': type_name, 'qos': qos}).encode()
        self._buf += FRAME.pack(TOPIC, tid, 0, len(body)) + body
        self.flush()

    def record(self, topic: str, data: bytes) -> None:
        tid = self.topics.get(topic)
        if tid is None or self.closed:
            return
        buf = self._buf
        buf += FRAME.pack(MESSAGE, tid, self._clock(), len(data))
        buf += data
        self.sent[topic] += 1
        if len(buf) >= FLUSH_BYTES:
            self.flush()

    def flush(self) -> None:
        """Hand what the buffer holds to the pipe, as much as it takes now (never waits)."""
        if not self._buf or self.closed:
            return
        try:
            n = os.write(self._fd, self._buf)
        except BlockingIOError:
            return
        except OSError:                # the writer died: counted, the loop goes on
            self.errors += 1
            self._buf.clear()
            return
        del self._buf[:n]

    def close(self, status: str, reason: str = '', timeout: float = 60.0) -> None:
        """Send the rest and the close frame, wait for the writer, take its counts."""
        if self.closed:
            return
        body = json.dumps({'status': status, 'reason': reason,
                           'part_errors': self.errors}).encode()
        self._buf += FRAME.pack(CLOSE, 0, 0, len(body)) + body
        os.set_blocking(self._fd, True)
        rest = bytes(self._buf)
        self._buf.clear()
        self.closed = True
        try:
            out, err = self.proc.communicate(input=rest, timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, err = self.proc.communicate()
        try:
            res = json.loads(out.decode().strip().splitlines()[-1])
            self._counts = {t: int(n) for t, n in res['counts'].items()}
            self.errors += int(res.get('errors', 0))
        except (ValueError, IndexError, KeyError):
            self.errors += 1
            self._counts = {}
            sys.stderr.write(f'[run] part writer for {self.path} failed: '
                             f'{err.decode(errors="replace")[-500:]}\n')


def _read_exact(f, n: int) -> bytes:
    data = f.read(n)
    return data if data is not None else b''


def write_part(stream, path: str, process: str) -> Dict[str, object]:
    """The writer process's work: frames from `stream` (binary, blocking) into a part file at
    `path`, until the close frame or the end of the stream (the worker ended without one:
    status interrupted). Returns {'counts', 'errors', 'status'}."""
    from catheter_bringup.local_recording import PartRecorder
    rec = PartRecorder(path, process)
    # held until this process ends: the runner's merge waits for it (`wait_written`), so a
    # part whose worker was killed is read only once its writer has closed it
    import fcntl
    lock = open(path, 'rb')
    fcntl.flock(lock, fcntl.LOCK_EX)
    names: Dict[int, str] = {}
    status, reason, errors = 'interrupted', 'the worker ended without closing its part', 0
    while True:
        head = _read_exact(stream, FRAME.size)
        if len(head) < FRAME.size:
            break
        kind, tid, t_ns, n = FRAME.unpack(head)
        body = _read_exact(stream, n)
        if len(body) < n:
            break                      # cut off: the worker died inside a frame
        if kind == MESSAGE:
            topic = names.get(tid)
            if topic is None:
                errors += 1
                continue
            rec.record(topic, body, t_ns)
        elif kind == TOPIC:
            d = json.loads(body)
            names[tid] = d['topic']
            rec.add_topic(d['topic'], d['type'], d['qos'])
        elif kind == CLOSE:
            d = json.loads(body)
            status, reason = d.get('status', 'complete'), d.get('reason', '')
            errors += int(d.get('part_errors', 0))
            break
        else:
            errors += 1
            break
    errors += rec.errors
    rec.close(status, reason)
    lock.close()
    return {'counts': rec.counts, 'errors': errors, 'status': status}


def wait_written(path, timeout: float = 20.0) -> bool:
    """Wait until no writer process holds the part at `path` (its lock); True when free or
    when there is no such file, False after `timeout` s."""
    import fcntl
    t_end = time.monotonic() + timeout
    try:
        f = open(path, 'rb')
    except OSError:
        return True
    with f:
        while True:
            try:
                fcntl.flock(f, fcntl.LOCK_SH | fcntl.LOCK_NB)
                return True
            except BlockingIOError:
                if time.monotonic() >= t_end:
                    return False
                time.sleep(0.02)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) != 2:
        print('usage: python -m catheter_bringup.part_pipe PART_PATH PROCESS', file=sys.stderr)
        return 2
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)    # Ctrl-C: the worker closes the pipe
    res = write_part(sys.stdin.buffer, argv[0], argv[1])
    print(json.dumps(res), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
