"""Recordings written by a process of their own (no rclpy).

A run's recording used to be written in the process that runs the nodes: the exact-length
walk, mcap's record packing and zstd on every chunk, inside the loop. In the split layout's
workers that cost the 1 kHz processes CPU at real-time priority, ahead of the vision process;
in lockstep it was a large part of the single-threaded run (figures: the package README,
"Benchmark"). `RecorderPipe` keeps only the cheap part in
the producer: each message's CDR bytes are appended to a buffer behind a 15-byte frame
header, and the buffer goes through a pipe to a writer process (``python -m
catheter_bringup.part_pipe PATH``, normal scheduling, started before a worker's loop takes
real-time priority; on the other core in lockstep), which writes them into an
`McapRecorder`. The pipe is non-blocking: a writer that falls behind never stalls the
producer, what the pipe does not take waits in the buffer. `PartPipe` is the same for a
worker's part file (`local_recording`).

Frames: ``<BHqI`` (kind, topic id, log time ns, payload length) + payload; kinds: TOPIC
(JSON {topic, type, qos}), MESSAGE (CDR bytes), START (JSON: the catheter_run_start
record), CLOSE (JSON {status, reason, extra}). At the end the writer closes the file and
prints its counts as one JSON line. A producer killed with SIGKILL closes the pipe by dying:
the writer takes every frame that reached the pipe and closes the file as ``interrupted``
("the process ended without closing its recording"; lost: at most the frames still in the
producer's buffer, `FLUSH_BYTES`); readers wait for the writer's lock (`wait_written`).
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
TOPIC, MESSAGE, CLOSE, START = 1, 2, 3, 4
#: bytes: the producer hands its buffer to the pipe once it holds this much (and at `flush`)
FLUSH_BYTES = 8 * 1024
#: bytes asked for the pipe (Linux F_SETPIPE_SZ; the default is 64 kB): over a second of a
#: master process's recording (about 7 000 messages a second, under 100 bytes each with
#: their frame headers) while the writer is not scheduled
PIPE_BYTES = 1 << 20
_F_SETPIPE_SZ = 1031


class RecorderPipe:
    """An `McapRecorder` written by a process of its own: `add_topic`, `write(topic, cdr,
    log_time_ns)`, `start(info)`, `close(status, reason, extra)`, `counts`, `closed` as
    McapRecorder (a bad topic name or an unknown type is refused here, at once; a payload the
    writer refuses is counted in `errors`), plus `record(topic, cdr)` (log time: now on the
    system clock; topics not added are ignored) and `flush` (hand the buffer to the pipe now;
    never waits)."""

    def __init__(self, path, library: str = 'catheter_bringup recorder',
                 chunk_size: int = 1 << 20, python: str = sys.executable):
        import pathlib
        p = pathlib.Path(path)
        if p.suffix != '.mcap':
            raise ValueError(f'path must end with .mcap, got {str(path)!r}')
        p.parent.mkdir(parents=True, exist_ok=True)
        self.path = str(path)
        self.topics: Dict[str, int] = {}
        self._types: Dict[str, str] = {}
        self.errors = 0
        self.closed = False
        self.sent: Dict[str, int] = {}
        self._counts: Optional[Dict[str, int]] = None
        self._buf = bytearray()
        self._clock = time.time_ns     # the system clock: what the nodes' clocks use
        self.proc = subprocess.Popen(
            [python, '-m', 'catheter_bringup.part_pipe', self.path, '--library', library,
             '--chunk-size', str(int(chunk_size))],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
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

    def has_topic(self, topic: str) -> bool:
        return topic in self.topics

    def _frame(self, kind: int, tid: int, t_ns: int, body: bytes) -> None:
        self._buf += FRAME.pack(kind, tid, t_ns, len(body))
        self._buf += body

    def add_topic(self, topic: str, type_name: str, qos: Optional[List[Mapping]] = None) -> int:
        from catheter_bringup.cdr import message_class
        from catheter_bringup.recorder import known_channel
        known = known_channel(topic, type_name, self.topics, self._types, self.closed)
        if known is not None:
            return known
        message_class(type_name)       # an unknown type is refused here (ImportError/ValueError)
        tid = self.topics[topic] = len(self.topics)
        self._types[topic] = type_name
        self.sent[topic] = 0
        self._frame(TOPIC, tid, 0, json.dumps({'topic': topic, 'type': type_name,
                                                'qos': list(qos) if qos else None}).encode())
        self.flush()
        return tid

    def write(self, topic: str, data: bytes, log_time_ns: int,
              publish_time_ns: Optional[int] = None) -> None:
        tid = self.topics.get(topic)
        if tid is None:
            raise ValueError(f'topic {topic!r} was not registered with add_topic')
        log_time_ns = int(log_time_ns)
        if log_time_ns < 0:
            raise ValueError(f'log_time_ns must be >= 0, got {log_time_ns}')
        if self.closed:
            return
        self._frame(MESSAGE, tid, log_time_ns, data)
        self.sent[topic] += 1
        if len(self._buf) >= FLUSH_BYTES:
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

    def start(self, info: Mapping[str, object]) -> None:
        """The ``catheter_run_start`` record (`McapRecorder.start`), written and flushed to
        the file by the writer before anything that follows."""
        if self.closed:
            raise ValueError('recorder is closed')
        self._frame(START, 0, 0, json.dumps(dict(info)).encode())
        # sent whole and acknowledged: the record is in the file when this returns (a run
        # killed before its first step still says what it was)
        os.set_blocking(self._fd, True)
        try:
            os.write(self._fd, bytes(self._buf))
            self._buf.clear()
        finally:
            os.set_blocking(self._fd, False)
        line = self.proc.stdout.readline()
        if line.strip() != b'started':
            raise RuntimeError(f'the recording writer for {self.path} did not start: '
                               f'{line[:200]!r}')

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

    def close(self, status: str = 'complete', reason: str = '',
              extra: Optional[Mapping[str, object]] = None, timeout: float = 120.0) -> None:
        """Send the rest and the close frame, wait for the writer, take its counts."""
        if status not in ('complete', 'interrupted', 'failed'):
            raise ValueError(f'status must be complete, interrupted or failed, got {status!r}')
        if self.closed:
            return
        self._frame(CLOSE, 0, 0, json.dumps({'status': status, 'reason': reason,
                                              'extra': dict(extra or {})}).encode())
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
            sys.stderr.write(f'[run] recording writer for {self.path} failed: '
                             f'{err.decode(errors="replace")[-500:]}\n')


class PartPipe(RecorderPipe):
    """The part file of one worker of the split layout (`local_recording.PartRecorder`'s
    interface), written by a process of its own: the loop only hands over bytes."""

    def __init__(self, path, process: str, python: str = sys.executable):
        from catheter_bringup.local_recording import PART_CHUNK
        super().__init__(path, library=f'catheter_bringup part ({process})',
                         chunk_size=PART_CHUNK, python=python)

    def close(self, status: str, reason: str = '', extra=None, timeout: float = 120.0) -> None:
        super().close(status, reason, dict(extra or {}, part_errors=self.errors), timeout)


def _frames(stream):
    """The complete frames of `stream` as (kind, topic id, log time ns, payload bytes), read
    in blocks of up to 1 MB (``read1``: what the pipe holds, waiting only when it is
    empty) instead of two reads per frame; ends at the end of the stream, or where a
    frame is cut off (the producer died inside it)."""
    read = getattr(stream, 'read1', None) or stream.read
    size = FRAME.size
    unpack = FRAME.unpack_from
    buf = bytearray()
    while True:
        b = read(1 << 20)
        if not b:
            return
        buf += b
        n, off = len(buf), 0
        out = []
        view = memoryview(buf)
        try:
            while n - off >= size:
                kind, tid, t_ns, length = unpack(buf, off)
                start = off + size
                if n - start < length:
                    break
                off = start + length
                out.append((kind, tid, t_ns, bytes(view[start:off])))
        finally:
            view.release()
        del buf[:off]
        yield from out


def write_stream(stream, recorder, ack=None) -> Dict[str, object]:
    """The writer process's work: frames from `stream` (binary, blocking) into `recorder`
    (an McapRecorder), until the close frame or the end of the stream (the producer ended
    without one: status interrupted); ``ack()`` after the start record is written.
    Returns {'counts', 'errors', 'status'}."""
    names: Dict[int, str] = {}
    status, reason, errors = 'interrupted', 'the process ended without closing its recording', 0
    extra: Dict[str, object] = {}
    start_info: Dict[str, object] = {}
    closed_by_producer = False
    write = recorder.write
    for kind, tid, t_ns, body in _frames(stream):
        if kind == MESSAGE:
            topic = names.get(tid)
            if topic is None:
                errors += 1
                continue
            try:
                write(topic, body, t_ns)
            except ValueError:
                errors += 1            # a payload the recorder refuses: counted, not fatal
        elif kind == TOPIC:
            d = json.loads(body)
            names[tid] = d['topic']
            recorder.add_topic(d['topic'], d['type'], d['qos'])
        elif kind == START:
            start_info = json.loads(body)
            recorder.start(start_info)
            if ack is not None:
                ack()
        elif kind == CLOSE:
            d = json.loads(body)
            status, reason = d.get('status', 'complete'), d.get('reason', '')
            extra = d.get('extra') or {}
            closed_by_producer = True
            break
        else:
            errors += 1
            break
    if not closed_by_producer:
        extra = dict(start_info)       # what the run was (as recover_bag carries it over)
    if 'part_errors' in extra:
        extra['part_errors'] = int(extra['part_errors']) + errors
    recorder.close(status, reason, extra=extra)
    return {'counts': dict(recorder.counts), 'errors': errors, 'status': status}


def write_part(stream, path: str, process: str) -> Dict[str, object]:
    """`write_stream` into a part file (as `PartPipe`'s writer writes it)."""
    from catheter_bringup.local_recording import PART_CHUNK
    from catheter_bringup.recorder import McapRecorder
    return write_stream(stream, McapRecorder(path, library=f'catheter_bringup part ({process})',
                                             chunk_size=PART_CHUNK))


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
    import argparse
    import fcntl
    import signal
    ap = argparse.ArgumentParser(prog='python -m catheter_bringup.part_pipe',
                                 description='writes the MCAP frames read from stdin')
    ap.add_argument('path')
    ap.add_argument('--library', default='catheter_bringup recorder')
    ap.add_argument('--chunk-size', type=int, default=1 << 20)
    try:
        a = ap.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    # its life is its producer's pipe: Ctrl-C, SIGTERM or SIGHUP sent to the whole process
    # group (a terminal, a launcher) stop the producer, which closes the pipe, and the file
    # is closed here after the last frame (only SIGKILL cuts it off)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)
    from catheter_bringup.recorder import McapRecorder
    rec = McapRecorder(a.path, library=a.library, chunk_size=a.chunk_size)
    # held until this process ends: a reader waits for it (`wait_written`), so a recording
    # whose producer was killed is read only once this writer has closed it
    lock = open(a.path, 'rb')
    fcntl.flock(lock, fcntl.LOCK_EX)
    res = write_stream(sys.stdin.buffer, rec, ack=lambda: print('started', flush=True))
    lock.close()
    print(json.dumps(res), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
