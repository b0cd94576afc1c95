"""analyze, replay, reprocess and plots answer a missing, truncated, empty or foreign file with
ONE clear line and a non-zero exit code (no traceback from inside the MCAP reader); a file cut
off anywhere is recovered by `recover_bag` into a file rosbags and mcap_ros2 read, with a
count of what was recovered; a run killed with SIGKILL has its recording closed by its writer
process, the run's scenario carried over."""
import json
import pathlib
import signal
import subprocess
import sys
import time

import pytest
from rclpy.serialization import serialize_message

from catheter_bringup import analyze, bagfile, plots, replay, reprocess
from catheter_bringup.recorder import McapRecorder, read_run_metadata

TOOLS = {'analyze': analyze.main, 'replay': replay.main, 'reprocess': reprocess.main,
         'plots': plots.main}


def _wrench(fx):
    from geometry_msgs.msg import WrenchStamped
    m = WrenchStamped()
    m.wrench.force.x = float(fx)
    return m


@pytest.fixture(scope='module')
def good(tmp_path_factory):
    path = tmp_path_factory.mktemp('good') / 'good.mcap'
    rec = McapRecorder(path, chunk_size=4096)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
    for k in range(2000):
        rec.write('/slave/force', serialize_message(_wrench(k * 1e-3)), k * 1_000_000)
    rec.close('complete')
    return path


def _bad_files(good, d):
    data = good.read_bytes()
    files = {'missing': d / 'missing.mcap', 'empty': d / 'empty.mcap',
             'truncated': d / 'truncated.mcap', 'foreign': d / 'foreign.mcap',
             'random': d / 'random.mcap'}
    files['empty'].write_bytes(b'')
    files['truncated'].write_bytes(data[:len(data) // 2])
    files['foreign'].write_text('{"not": "a bag"}\n')
    files['random'].write_bytes(bytes((i * 7919 + 13) % 256 for i in range(5000)))
    return files


EXPECT = {'missing': 'no such file', 'empty': 'empty file (0 bytes)',
          'truncated': 'cut off, no summary', 'foreign': 'not an MCAP file',
          'random': 'not an MCAP file'}


@pytest.mark.parametrize('tool', sorted(TOOLS))
def test_a_bad_file_gets_one_clear_line_and_exit_code_2(tool, good, tmp_path, capsys):
    for kind, path in _bad_files(good, tmp_path).items():
        code = TOOLS[tool]([str(path)])
        out, err = capsys.readouterr()
        lines = [line for line in (out + err).splitlines() if line.strip()]
        assert code == 2, (tool, kind, out, err)
        assert len(lines) == 1, (tool, kind, lines)
        assert lines[0].startswith(f'{tool}: {path}: ') and EXPECT[kind] in lines[0], lines
        assert 'Traceback' not in out + err


def test_a_cut_off_file_points_at_recover_bag(good, tmp_path):
    p = _bad_files(good, tmp_path)['truncated']
    with pytest.raises(bagfile.BagError, match=f'recover_bag {p}'):
        bagfile.check_bag(p)


def test_a_ros_less_mcap_is_refused_as_foreign(tmp_path):
    from mcap.writer import Writer
    p = tmp_path / 'json.mcap'
    with open(p, 'wb') as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema('x', 'jsonschema', b'{}')
        cid = w.register_channel('/x', 'json', sid)
        w.add_message(cid, 0, b'{}', 0)
        w.finish()
    with pytest.raises(bagfile.BagError, match='not a ROS 2 recording'):
        bagfile.check_bag(p)


def test_recover_rebuilds_a_stream_cut_anywhere(good, tmp_path):
    """Cut the good file at many places: recover_bag returns what precedes the cut (whole
    chunks), never more than was written, and the result is a complete, readable bag."""
    from mcap_ros2.reader import read_ros2_messages
    data = good.read_bytes()
    seen = []
    for frac in (0.1, 0.35, 0.6, 0.85, 0.99):
        cut = tmp_path / f'cut_{frac}.mcap'
        cut.write_bytes(data[:int(len(data) * frac)])
        res = bagfile.recover(cut)
        out = pathlib.Path(res['output'])
        bagfile.check_bag(out)
        xs = [m.ros_msg.wrench.force.x for m in read_ros2_messages(str(out))]
        assert len(xs) == res['messages'] == res['topics']['/slave/force']
        assert xs == [k * 1e-3 for k in range(len(xs))]          # a prefix, in order
        meta = read_run_metadata(out)
        # cut before the writer's close: interrupted; after its catheter_run record (only the
        # summary lost): that record, complete
        assert (meta['status'] == 'interrupted' and meta['messages'] == str(len(xs))) or \
            (meta['status'] == 'complete' and len(xs) == 2000), (frac, meta)
        seen.append(len(xs))
    assert seen == sorted(seen) and seen[-1] > 1500 and seen[0] < 500
    with pytest.raises(bagfile.BagError, match='nothing to recover'):
        bagfile.recover(good)
    with pytest.raises(bagfile.BagError, match='not an MCAP file'):
        bagfile.recover(_bad_files(good, tmp_path)['foreign'])


@pytest.mark.slow
@pytest.mark.ros
def test_a_sigkilled_runs_recording_is_closed_by_its_writer(tmp_path):
    """run_scenario killed with SIGKILL mid-run: its recording's writer (a process of its
    own, `part_pipe`) outlives it, takes what reached the pipe and closes the file as
    interrupted with the run's scenario; rosbags, mcap_ros2 and analyze read it (recover_bag
    is left for files whose writer died too: `test_recover_rebuilds_a_stream_cut_anywhere`)."""
    from catheter_bringup.part_pipe import wait_written
    bag = tmp_path / 'killed.mcap'
    exe = [sys.executable, '-m', 'catheter_bringup.run_scenario', 'smoke', '--duration', '60',
           '--bag', str(bag), '--quiet']
    proc = subprocess.Popen(exe, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        t_end = time.monotonic() + 60
        while time.monotonic() < t_end and (not bag.exists() or bag.stat().st_size < 600_000):
            time.sleep(0.2)
            assert proc.poll() is None, proc.stdout.read()
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert wait_written(bag, timeout=60)
    meta = read_run_metadata(bag)
    assert meta['status'] == 'interrupted' and 'without closing' in meta['reason'], meta
    assert meta['scenario'] == 'smoke' and 'scenario_yaml' in meta
    n = int(meta['messages'])
    assert n > 3_000 and sum(json.loads(meta['counts']).values()) == n
    with pytest.raises(bagfile.BagError, match='nothing to recover'):
        bagfile.recover(bag)
    from rosbags.highlevel import AnyReader
    with AnyReader([bag]) as reader:
        count = sum(1 for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype))
    assert count == n
    from mcap_ros2.reader import read_ros2_messages
    assert sum(1 for _ in read_ros2_messages(str(bag))) == n
    assert analyze.main([str(bag), '--quiet']) == 0
    res = analyze.analyze(bag)
    assert 'warnings' not in res and res['delay_s'] == 0.2
    assert res['force_tracking']['ima']['all']['n'] > 0


def _chunk_records_offset(path):
    """Byte offset of the compressed records of the middle chunk of an indexed MCAP file."""
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        summary = make_reader(f).get_summary()
    ci = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    # chunk record: opcode, length, start, end, uncompressed size, crc, compression, records
    return ci.chunk_start_offset + 1 + 8 + 8 + 8 + 8 + 4 + 4 + len(ci.compression) + 8, ci


def test_a_damaged_chunk_in_an_indexed_file_gets_one_clear_line(good, tmp_path, capsys):
    """The summary is intact, so check_bag passes; the damage is met while reading: the
    decompressor's error must become the one-line BagError, not a traceback."""
    from catheter_bringup.recording import load
    pos, ci = _chunk_records_offset(good)
    assert ci.compression == 'zstd'
    data = bytearray(good.read_bytes())
    assert data[pos:pos + 4] == bytes.fromhex('28b52ffd')        # the zstd frame magic
    data[pos:pos + 4] = b'\0\0\0\0'
    bad = tmp_path / 'damaged.mcap'
    bad.write_bytes(bytes(data))
    bagfile.check_bag(bad)                                      # the index is intact
    with pytest.raises(bagfile.BagError, match='unreadable'):
        load(bad)
    assert analyze.main([str(bad)]) == 2
    out, err = capsys.readouterr()
    assert 'Traceback' not in out + err and f'analyze: {bad}: unreadable' in err


@pytest.mark.parametrize('offset', list(range(90, 400, 7)))
def test_a_flipped_bit_in_a_chunk_is_an_unreadable_file_not_other_values(good, tmp_path,
                                                                          offset):
    """One bit flipped inside a compressed chunk (the index intact): the chunk's CRC is
    checked, so the analysis refuses the file in one line. Unchecked, most of these offsets
    decoded to other forces without any error, and some to a channel id no channel has
    (a KeyError traceback)."""
    from catheter_bringup.recording import load
    pos, _ = _chunk_records_offset(good)
    data = bytearray(good.read_bytes())
    data[pos + offset] ^= 0x10
    bad = tmp_path / 'flipped.mcap'
    bad.write_bytes(bytes(data))
    with pytest.raises(bagfile.BagError, match='unreadable'):
        load(bad)


def _flipped(src, dst, offset=150):
    """A copy of ``src`` with one bit flipped inside its middle chunk's compressed records."""
    pos, _ = _chunk_records_offset(src)
    data = bytearray(pathlib.Path(src).read_bytes())
    data[pos + offset] ^= 0x10
    dst.write_bytes(bytes(data))
    bagfile.check_bag(dst)                                      # the index is intact
    return dst


def test_read_messages_checks_the_chunks_crcs(good, tmp_path):
    """The shared reader: every message of the intact file, in order (raw and decoded); the
    flipped file raises the one-line BagError (unchecked, it read other forces)."""
    raw = list(bagfile.read_messages(good))
    assert [m.log_time for _, _, m in raw] == [k * 1_000_000 for k in range(2000)]
    dec = list(bagfile.read_messages(good, ['/slave/force'], decode=True))
    assert [d.wrench.force.x for *_, d in dec] == pytest.approx([k * 1e-3 for k in range(2000)])
    assert list(bagfile.read_messages(good, ['/no/such/topic'])) == []
    bad = _flipped(good, tmp_path / 'flipped.mcap')
    with pytest.raises(bagfile.BagError, match=f'^{bad}: unreadable .*CRC'):
        list(bagfile.read_messages(bad))
    with pytest.raises(bagfile.BagError, match='unreadable'):
        list(bagfile.read_messages(bad, decode=True))


def test_replay_of_a_flipped_chunk_stops_there_with_one_line(good, tmp_path, ros, capsys):
    """replay republished the damaged chunk's messages as other values; now it stops at that
    chunk with the BagError."""
    bad = _flipped(good, tmp_path / 'flipped.mcap')
    node = ros.node('replay')
    with pytest.raises(bagfile.BagError, match='unreadable'):
        replay.replay(bad, rate=1e4, clock=False, node=node)
    res = replay.replay(good, rate=1e4, clock=False, node=node)
    assert res['published'] == {'/slave/force': 2000}          # the intact file: all of it
    # the library's one line reaches the user through the tool's error path
    capsys.readouterr()
    code = bagfile.cli_errors('replay', lambda: replay.replay(bad, rate=1e4, clock=False,
                                                             node=node))
    assert code == 2
    out, err = capsys.readouterr()
    assert out == '' and len(err.splitlines()) == 1
    assert err.startswith(f'replay: {bad}: unreadable') and 'Traceback' not in err


def test_reprocess_of_a_flipped_chunk_is_refused_in_one_line(tmp_path, capsys):
    """reprocess read the recorded inputs unchecked, so it re-ran nodes on other values and
    reported them CHANGED (or same); now the file is refused before any node runs."""
    ref = sorted((pathlib.Path(__file__).resolve().parents[2] / 'bags' / 'reference')
                 .glob('*.mcap'))[0]
    bad = _flipped(ref, tmp_path / 'flipped_ref.mcap')
    assert reprocess.main([str(bad)]) == 2
    out, err = capsys.readouterr()
    lines = [line for line in (out + err).splitlines() if line.strip()]
    assert lines == [line for line in lines if line.startswith(f'reprocess: {bad}: unreadable')]
    assert len(lines) == 1 and 'Traceback' not in out + err


def test_compare_streams_refuses_a_flipped_recording(good, tmp_path):
    assert reprocess.compare_streams(good, good, '/slave/force')['max_diff'] == 0.0
    bad = _flipped(good, tmp_path / 'flipped.mcap')
    for a, b in ((good, bad), (bad, good)):
        with pytest.raises(bagfile.BagError, match='unreadable'):
            reprocess.compare_streams(a, b, '/slave/force')


def test_a_cdr_channel_without_a_ros2msg_schema_is_refused(tmp_path):
    """Message encoding cdr but a jsonschema schema: no ROS 2 reader can decode it."""
    from mcap.writer import Writer
    p = tmp_path / 'cdr_json_schema.mcap'
    with open(p, 'wb') as f:
        w = Writer(f)
        w.start(profile='ros2')
        sid = w.register_schema('geometry_msgs/msg/WrenchStamped', 'jsonschema', b'{}')
        cid = w.register_channel('/slave/force', 'cdr', sid)
        w.add_message(cid, 0, serialize_message(_wrench(1.0)), 0)
        w.finish()
    with pytest.raises(bagfile.BagError, match='channel /slave/force: no ros2msg schema'):
        bagfile.check_bag(p)


def test_recovery_keeps_publish_times_and_sequence_numbers(tmp_path):
    """recover_bag copies each message's publish time and sequence number, not only its log
    time: compared message by message with the original file, read with mcap's reader."""
    from mcap.reader import make_reader
    path = tmp_path / 'pub.mcap'
    rec = McapRecorder(path, chunk_size=4096)
    rec.add_topic('/slave/force', 'geometry_msgs/msg/WrenchStamped')
    for k in range(600):
        rec.write('/slave/force', serialize_message(_wrench(k)), 10_000_000 + k * 1_000_000,
                  publish_time_ns=k * 1_000_000 + 7)
    rec.close('complete')

    def triples(p):
        with open(p, 'rb') as f:
            return [(m.log_time, m.publish_time, m.sequence)
                    for _, _, m in make_reader(f).iter_messages(log_time_order=True)]
    original = triples(path)
    assert original[5] == (15_000_000, 5_000_007, 5)
    cut = tmp_path / 'pub_cut.mcap'
    cut.write_bytes(path.read_bytes()[:int(path.stat().st_size * 0.7)])
    res = bagfile.recover(cut)
    got = triples(res['output'])
    assert 100 < len(got) < 600 and got == original[:len(got)]


def _schema_record():
    """A well-formed MCAP Schema record (opcode 3): id 1, name 'x', encoding ros2msg."""
    import struct

    def string(b):
        return struct.pack('<I', len(b)) + b
    content = struct.pack('<H', 1) + string(b'x') + string(b'ros2msg') + string(b'')
    return b'\x03' + struct.pack('<Q', len(content)) + content


@pytest.mark.parametrize('data', [b'\x89MCAP0\r\n', b'\x89MCAP0\r\n' + _schema_record(),
                                  b'\x89MCAP0\r\n\x03' + (100).to_bytes(8, 'little') + b'x' * 20],
                         ids=['magic-only', 'schema-before-header', 'cut-record'])
def test_a_file_without_a_header_record_is_not_recoverable_and_leaves_nothing(data, tmp_path):
    p = tmp_path / 'h.mcap'
    p.write_bytes(data)
    with pytest.raises(bagfile.BagError, match='no MCAP header record: not recoverable'):
        bagfile.recover(p)
    assert sorted(x.name for x in tmp_path.iterdir()) == ['h.mcap']


def test_recover_refuses_to_write_over_its_input_and_the_command_reports(good, tmp_path,
                                                                        capsys):
    data = good.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(bagfile.BagError, match='must not be the input'):
        bagfile.recover(cut, cut)
    assert cut.read_bytes() == data[:len(data) // 2]
    out = tmp_path / 'fixed.mcap'
    assert bagfile.main([str(cut), '-o', str(out)]) == 0
    text = capsys.readouterr().out.splitlines()
    res = bagfile.recover(cut, tmp_path / 'again.mcap')
    assert text[0] == (f"recovered {res['messages']} messages on 1 topics (1 schemas) -> {out}")
    assert text[1] == f"  lost: the last {res['unreadable_tail_bytes']} bytes (an incomplete chunk)"
    assert res['unreadable_tail_bytes'] > 0 and text[-1].split() == ['/slave/force',
                                                                      str(res['messages'])]
    bagfile.check_bag(out)
    assert bagfile.main([str(good)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'nothing to recover' in err[0]


def test_format_recovery_says_what_was_lost_and_what_is_missing():
    res = dict(output='o.mcap', messages=3, topics={'/b': 1, '/a': 2}, schemas=1,
               channels=2, metadata=[], unreadable_tail_bytes=0, stopped_at='')
    lines = bagfile.format_recovery(res).splitlines()
    assert lines[1] == '  lost: nothing (the stream ended cleanly)'
    assert lines[2].startswith('  no run metadata (catheter_run_start) in the file')
    assert [ln.split() for ln in lines[3:]] == [['/a', '2'], ['/b', '1']]
    res['metadata'] = [bagfile.RUN_START_METADATA]
    assert not any('no run metadata' in ln for ln in bagfile.format_recovery(res).splitlines())
