"""The split layout's recording written by a process of its own (catheter_bringup.part_pipe):
what the worker hands over is what the part holds, in order, with the worker's log times;
a worker that dies mid-frame leaves a part closed as interrupted with every whole frame;
the merge waits for a writer that still holds its part."""
import io
import json
import subprocess
import sys
import time

import pytest

from catheter_bringup import part_pipe as P
from catheter_bringup.local_recording import read_part

pytestmark = pytest.mark.ros


def _cdr():
    from geometry_msgs.msg import WrenchStamped
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    out = []
    for k in range(400):                    # ~60 kB: several hand-overs of the buffer
        w = WrenchStamped()
        w.wrench.force.x = float(k)
        out.append(('/w', serialize_message(w)))
        out.append(('/js', serialize_message(JointState(position=[k * 1e-3]))))
    return out


def test_what_the_worker_hands_over_is_what_the_part_holds(tmp_path):
    path = tmp_path / 'run.master.part.mcap'
    pipe = P.PartPipe(path, 'master')
    pipe.add_topic('/w', 'geometry_msgs/msg/WrenchStamped', None)
    pipe.add_topic('/js', 'sensor_msgs/msg/JointState', None)
    msgs = _cdr()
    for topic, data in msgs:
        pipe.record(topic, data)
    pipe.record('/not_added', b'\x00\x01\x00\x00')         # ignored, as PartRecorder does
    pipe.close('complete', 'end of the test')
    assert pipe.counts == {'/w': 400, '/js': 400} and pipe.errors == 0
    channels, got, info = read_part(path)
    assert set(channels) == {'/w', '/js'}
    assert info['complete'] and info['status'] == 'complete' and info['messages'] == 800
    assert info['reason'] == 'end of the test'
    # the same payloads in the same order (the recorder cuts rclpy's padding: a prefix)
    assert [t for _, _, t, _ in got] == [t for t, _ in msgs]
    for (_, _, _, data), (_, sent) in zip(got, msgs, strict=True):
        assert sent.startswith(bytes(data))
    times = [t for t, _, _, _ in got]
    assert times == sorted(times) and abs(times[0] - time.time_ns()) < 60e9
    pipe.record('/w', msgs[0][1])                           # after close: nothing, no error
    pipe.close('complete')
    assert pipe.counts['/w'] == 400


def test_a_stream_cut_inside_a_frame_closes_the_part_as_interrupted(tmp_path):
    buf = io.BytesIO()
    body = json.dumps({'topic': '/w', 'type': 'geometry_msgs/msg/WrenchStamped',
                       'qos': None}).encode()
    buf.write(P.FRAME.pack(P.TOPIC, 0, 0, len(body)) + body)
    data = _cdr()[0][1]
    for k in range(5):
        buf.write(P.FRAME.pack(P.MESSAGE, 0, 1000 + k, len(data)) + data)
    whole = buf.getvalue()
    # the worker died inside the sixth message frame
    cut = whole + P.FRAME.pack(P.MESSAGE, 0, 2000, len(data)) + data[:3]
    path = tmp_path / 'cut.part.mcap'
    res = P.write_part(io.BytesIO(cut), str(path), 'master')
    assert res['status'] == 'interrupted' and res['counts'] == {'/w': 5}
    _, got, info = read_part(path)
    assert info['complete'] and info['status'] == 'interrupted'
    assert 'without closing' in info['reason']
    assert [t for t, _, _, _ in got] == [1000, 1001, 1002, 1003, 1004]
    # a message of a topic never announced, then a frame of an unknown kind: counted errors
    bad = whole + P.FRAME.pack(P.MESSAGE, 7, 3000, len(data)) + data + \
        P.FRAME.pack(99, 0, 0, 0)
    res = P.write_part(io.BytesIO(bad), str(tmp_path / 'bad.part.mcap'), 'master')
    assert res['errors'] == 2 and res['counts'] == {'/w': 5}


def test_the_merge_waits_for_a_writer_that_holds_its_part(tmp_path):
    path = tmp_path / 'held.part.mcap'
    path.write_bytes(b'')
    assert P.wait_written(tmp_path / 'missing.part.mcap', timeout=0.1)
    holder = subprocess.Popen([sys.executable, '-c', (
        'import fcntl, sys, time\n'
        f'f = open({str(path)!r}, "rb"); fcntl.flock(f, fcntl.LOCK_EX)\n'
        'print("held", flush=True); time.sleep(1.0)\n')], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == 'held'
        assert not P.wait_written(path, timeout=0.2)          # still held: not read yet
        t0 = time.monotonic()
        assert P.wait_written(path, timeout=10.0)             # free once the writer exits
        assert time.monotonic() - t0 < 5.0
    finally:
        holder.kill()
        holder.wait()


def test_the_writer_command_refuses_wrong_arguments():
    assert P.main([]) == 2
    assert P.main(['x.mcap', '--chunk-size', 'big']) == 2


def test_a_writer_that_dies_is_not_hidden(tmp_path, monkeypatch):
    """The writer process killed mid-run: the producer goes on (counted errors, no
    exception in the loop) and its counts say what reached the file, not what was sent."""
    pipe = P.RecorderPipe(tmp_path / 'w.mcap', chunk_size=4096)
    pipe.add_topic('/w', 'geometry_msgs/msg/WrenchStamped', None)
    data = _cdr()[0][1]
    for k in range(10):
        pipe.write('/w', data, k)
    pipe.flush()
    pipe.proc.kill()
    pipe.proc.wait()
    for k in range(10, 3000):
        pipe.write('/w', data, k)                # BrokenPipe inside: counted, not raised
    pipe.close('complete')
    assert pipe.errors > 0
    assert pipe.counts.get('/w', 0) < 3000
    with pytest.raises(ValueError, match='not registered'):
        pipe.write('/nope', data, 1)
    with pytest.raises(ValueError, match='topic must be'):
        pipe.add_topic('relative', 'geometry_msgs/msg/WrenchStamped')
    with pytest.raises(ValueError, match='status'):
        pipe.close('fine')


def test_the_writer_outlives_signals_sent_to_the_process_group(tmp_path):
    """SIGINT, SIGTERM and SIGHUP (a terminal's Ctrl-C, a launcher's stop) reach the writer
    too: it ignores them and closes the file once its producer closes the pipe."""
    import signal
    pipe = P.RecorderPipe(tmp_path / 's.mcap', chunk_size=4096)
    pipe.add_topic('/w', 'geometry_msgs/msg/WrenchStamped', None)
    pipe.start({'scenario': 'signals'})             # acknowledged: the writer is running
    data = _cdr()[0][1]
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        pipe.write('/w', data, 1)
        pipe.proc.send_signal(sig)
    time.sleep(0.2)
    assert pipe.proc.poll() is None
    pipe.close('interrupted', 'SIGTERM')
    assert pipe.counts == {'/w': 3} and pipe.errors == 0
    from catheter_bringup.recorder import read_run_metadata
    meta = read_run_metadata(tmp_path / 's.mcap')
    assert meta['status'] == 'interrupted' and meta['reason'] == 'SIGTERM'


@pytest.mark.parametrize('kind', ['mcap', 'part'])
def test_add_topic_checks_are_the_same_for_both_recorders(tmp_path, kind):
    """McapRecorder and PartPipe share `recorder.known_channel`: an absolute name, one type
    per topic, the same id for a repeat, nothing added once closed."""
    from catheter_bringup.recorder import McapRecorder
    rec = (McapRecorder(str(tmp_path / 'a.mcap')) if kind == 'mcap'
           else P.PartPipe(tmp_path / 'a.master.part.mcap', 'master'))
    wrench = 'geometry_msgs/msg/WrenchStamped'
    first = rec.add_topic('/w', wrench, None)
    assert rec.add_topic('/w', wrench, None) == first
    with pytest.raises(ValueError, match='absolute name'):
        rec.add_topic('w', wrench, None)
    with pytest.raises(ValueError, match='already recorded as'):
        rec.add_topic('/w', 'sensor_msgs/msg/JointState', None)
    rec.close('complete')
    with pytest.raises(ValueError, match='closed'):
        rec.add_topic('/js', 'sensor_msgs/msg/JointState', None)


class _Chunks:
    """A binary stream whose read1 returns at most `size` bytes at a time (a pipe that hands
    over what it holds)."""

    def __init__(self, data: bytes, size: int):
        self.data, self.size, self.pos = data, size, 0

    def read1(self, n):
        b = self.data[self.pos:self.pos + min(n, self.size)]
        self.pos += len(b)
        return b


@pytest.mark.parametrize('size', [1, 7, 15, 16, 1000, 1 << 20])
def test_the_writers_frames_are_reassembled_across_reads_and_a_cut_one_is_dropped(size):
    """`part_pipe._frames`: frames split anywhere by the pipe's reads come out whole, in
    order; a last frame cut off (the producer died inside it) is not yielded."""
    from catheter_bringup.part_pipe import FRAME, MESSAGE, TOPIC, _frames
    bodies = [b'', b'x', bytes(range(200)) * 3, b'{"topic": "/a"}', b'\x00' * 70]
    kinds = [MESSAGE, MESSAGE, MESSAGE, TOPIC, MESSAGE]
    data = b''.join(FRAME.pack(k, i, 1000 + i, len(b)) + b
                    for i, (k, b) in enumerate(zip(kinds, bodies, strict=True)))
    want = [(k, i, 1000 + i, b) for i, (k, b) in enumerate(zip(kinds, bodies, strict=True))]
    assert list(_frames(_Chunks(data, size))) == want
    cut = data + FRAME.pack(MESSAGE, 9, 9, 50) + b'y' * 49        # one byte short
    assert list(_frames(_Chunks(cut, size))) == want
    assert list(_frames(_Chunks(data + FRAME.pack(MESSAGE, 9, 9, 5)[:7], size))) == want
