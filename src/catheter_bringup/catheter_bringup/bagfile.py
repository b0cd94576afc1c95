"""Recordings that are missing, empty, foreign or cut off (no rclpy): one clear message, and a
recovery for a killed run (the `ros2 bag reindex` of this project).

`check_bag(path)` raises `BagError` (a ValueError) with ONE line saying what is wrong:

    bags/x.mcap: no such file
    bags/x.mcap: empty file (0 bytes)
    bags/x.mcap: not an MCAP file (it does not start with the MCAP magic bytes)
    bags/x.mcap: not a ROS 2 recording (channel /a: message encoding json)
    bags/x.mcap: cut off, no summary (a killed run?): recover it with `recover_bag bags/x.mcap`

The tools (analyze, replay, reprocess, plots) check their input first and print that line
(exit code 2) instead of a traceback from deep inside the MCAP reader.

`recover(path, out)` reads a recording that has no summary (a SIGKILL'd run: the MCAP writer
never wrote its index) record by record with mcap's StreamReader, up to the first record that
is incomplete, and writes every schema, channel, message and metadata record it holds into a
new, indexed file; the recording's ``catheter_run_start`` metadata (scenario, mode, ...,
written when the run started) becomes its ``catheter_run`` record with status
``interrupted``. What was lost is at most the chunk being filled when the process died (the
runner's chunks: 64 kB in real time, 1 MB in lockstep) and the writer's unflushed buffer.

    recover_bag bags/experiment_ii.mcap            # -> bags/experiment_ii_recovered.mcap
    recover_bag bags/x.mcap -o /tmp/y.mcap
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import pathlib
import sys
from typing import Callable, Dict, Iterable, Iterator, Optional

from catheter_bringup.recorder import RUN_METADATA, RUN_START_METADATA

MAGIC = b'\x89MCAP0\r\n'


class BagError(ValueError):
    """A recording that cannot be read as it is; the message is one line for the user."""


def check_bag(path: str | os.PathLike) -> None:
    """Raise BagError (one line) unless ``path`` is a complete MCAP file of ROS 2 messages."""
    from mcap.reader import make_reader
    p = pathlib.Path(path)
    if not p.exists():
        raise BagError(f'{path}: no such file')
    if p.is_dir():
        raise BagError(f'{path}: is a directory, not an .mcap file')
    if p.stat().st_size == 0:
        raise BagError(f'{path}: empty file (0 bytes)')
    with open(p, 'rb') as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise BagError(f'{path}: not an MCAP file (it does not start with the MCAP magic '
                           'bytes)')
        f.seek(0)
        try:
            summary = make_reader(f).get_summary()
        except Exception:  # noqa: BLE001 - any reader error here means: no intact footer
            summary = None
    if summary is None:
        raise BagError(f'{path}: cut off, no summary (a killed run?): recover it with '
                       f'`recover_bag {path}`')
    for ch in summary.channels.values():
        schema = summary.schemas.get(ch.schema_id)
        if ch.message_encoding != 'cdr' or schema is None or schema.encoding != 'ros2msg':
            what = f'message encoding {ch.message_encoding}' if ch.message_encoding != 'cdr' \
                else 'no ros2msg schema'
            raise BagError(f'{path}: not a ROS 2 recording (channel {ch.topic}: {what})')


@contextlib.contextmanager
def reading(path: str | os.PathLike) -> Iterator[None]:
    """Check ``path`` first; turn an error of the MCAP reader while reading it into a
    one-line BagError (a damaged chunk in the middle of an indexed file)."""
    check_bag(path)
    from mcap.exceptions import McapError
    from zstandard import ZstdError
    try:
        yield
    except BagError:
        raise
    # a damaged chunk fails in the decompressor (ZstdError) or as an absurd record length or
    # string (OverflowError, ValueError, UnicodeDecodeError) as often as in the reader itself
    except (McapError, EOFError, ZstdError, OverflowError, ValueError) as exc:
        raise BagError(f'{path}: unreadable ({type(exc).__name__}: {exc})'.splitlines()[0]) \
            from None


def read_messages(path: str | os.PathLike, topics: Optional[Iterable[str]] = None,
                  decode: bool = False) -> Iterator[tuple]:
    """Every message of the recording at ``path`` in log-time order, checked first and read
    with the chunks' CRCs checked: ``(schema, channel, message)``, or with ``decode``
    ``(schema, channel, message, ros_msg)`` (mcap_ros2's decoder).

    Unchecked, one flipped bit inside a compressed chunk often decodes to other values
    without any error; here it, like any reader error, is a one-line BagError."""
    from mcap.reader import make_reader
    factories = []
    if decode:
        from mcap_ros2.decoder import DecoderFactory
        factories = [DecoderFactory()]
    want = list(topics) if topics is not None else None
    with reading(path), open(path, 'rb') as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=factories)
        if decode:
            yield from reader.iter_decoded_messages(topics=want, log_time_order=True)
        else:
            yield from reader.iter_messages(topics=want, log_time_order=True)


def cli_errors(prog: str, main_body: Callable[..., int], *args) -> int:
    """Run a tool's body; a BagError becomes ``prog: message`` on stderr and exit code 2."""
    try:
        return main_body(*args)
    except BagError as exc:
        print(f'{prog}: {exc}', file=sys.stderr)
        return 2


def recover(path: str | os.PathLike, out: Optional[str | os.PathLike] = None
            ) -> Dict[str, object]:
    """Rewrite the readable part of a cut-off recording into ``out`` (default
    ``<stem>_recovered.mcap`` beside it); returns what was recovered: messages, per-topic
    counts, schemas, channels, metadata records, and the bytes at the end that could not be
    read. BagError when the file is missing, empty, not MCAP, or already complete."""
    from mcap.stream_reader import StreamReader
    from mcap.records import Channel, Header, Message, Metadata, Schema
    from mcap.writer import CompressionType, Writer
    p = pathlib.Path(path)
    try:
        check_bag(p)
    except BagError as exc:
        if 'cut off' not in str(exc):
            raise
    else:
        raise BagError(f'{path}: complete (it has its summary): nothing to recover')
    out = pathlib.Path(out) if out is not None else p.with_name(f'{p.stem}_recovered.mcap')
    if out.resolve() == p.resolve():
        raise BagError(f'{out}: the output must not be the input')
    size = p.stat().st_size
    schemas: Dict[int, int] = {}
    channels: Dict[int, int] = {}
    topics: Dict[int, str] = {}
    counts: Dict[str, int] = {}
    metadata: Dict[str, Dict[str, str]] = {}
    first = last = None
    n = 0
    stopped = ''
    with open(p, 'rb') as f, open(out, 'wb') as g:
        w = Writer(g, chunk_size=1 << 20, compression=CompressionType.ZSTD)
        started = False
        reader = StreamReader(f, skip_magic=False, emit_chunks=False)
        good = 0
        try:
            for rec in reader.records:
                if isinstance(rec, Header):
                    w.start(profile=rec.profile, library=f'{rec.library} (recovered)')
                    started = True
                elif not started:
                    raise BagError(f'{path}: no MCAP header record: not recoverable')
                elif isinstance(rec, Schema):
                    if rec.id not in schemas:
                        schemas[rec.id] = w.register_schema(rec.name, rec.encoding, rec.data)
                elif isinstance(rec, Channel):
                    if rec.id not in channels and rec.schema_id in schemas:
                        channels[rec.id] = w.register_channel(
                            rec.topic, rec.message_encoding, schemas[rec.schema_id],
                            dict(rec.metadata))
                        topics[rec.id] = rec.topic
                        counts.setdefault(rec.topic, 0)
                elif isinstance(rec, Message):
                    cid = channels.get(rec.channel_id)
                    if cid is None:
                        continue
                    w.add_message(cid, rec.log_time, rec.data, rec.publish_time, rec.sequence)
                    counts[topics[rec.channel_id]] += 1
                    n += 1
                    first = rec.log_time if first is None else min(first, rec.log_time)
                    last = rec.log_time if last is None else max(last, rec.log_time)
                elif isinstance(rec, Metadata):
                    metadata[rec.name] = dict(rec.metadata)
                good = f.tell()
        except BagError:
            g.close()
            out.unlink()
            raise
        except Exception as exc:  # noqa: BLE001 - the cut: whatever the reader tripped on
            stopped = f'{type(exc).__name__}'
        if not started:
            g.close()
            out.unlink()
            raise BagError(f'{path}: no MCAP header record: not recoverable')
        for name, data in metadata.items():
            if name != RUN_METADATA:
                w.add_metadata(name, data)
        run = dict(metadata.get(RUN_METADATA) or {})
        if not run:
            run = {k: v for k, v in metadata.get(RUN_START_METADATA, {}).items()
                   if k != 'status'}
            mode = run.get('mode', '')
            reached = (last or 0) * 1e-9 if mode == 'lockstep' else \
                ((last - first) * 1e-9 if first is not None else 0.0)
            run.update(status='interrupted',
                       reason='killed: recovered by recover_bag from a recording without '
                              'summary',
                       messages=str(n), counts=json.dumps(counts, sort_keys=True),
                       first_log_time_ns=str(first if first is not None else -1),
                       last_log_time_ns=str(last if last is not None else -1),
                       sim_time_reached_s=str(round(reached, 6)))
        w.add_metadata(RUN_METADATA, run)
        w.finish()
    return {'output': str(out), 'messages': n, 'topics': counts, 'schemas': len(schemas),
            'channels': len(channels), 'metadata': sorted(metadata),
            'unreadable_tail_bytes': size - good, 'stopped_at': stopped,
            'scenario': run.get('scenario', '')}


def format_recovery(res: Dict[str, object]) -> str:
    lines = [f"recovered {res['messages']} messages on {len(res['topics'])} topics "
             f"({res['schemas']} schemas) -> {res['output']}",
             f"  lost: the last {res['unreadable_tail_bytes']} bytes (an incomplete chunk)"
             if res['unreadable_tail_bytes'] else '  lost: nothing (the stream ended cleanly)']
    if not res['metadata'] or RUN_START_METADATA not in res['metadata']:
        lines.append('  no run metadata (catheter_run_start) in the file: analyze will '
                     'assume the link delay and outages')
    for topic, c in sorted(res['topics'].items()):
        lines.append(f'  {topic:<32} {c:>8}')
    return '\n'.join(lines)


def main(argv: Optional[list] = None) -> int:
    ap = argparse.ArgumentParser(prog='recover_bag', description=__doc__.split('\n\n')[0])
    ap.add_argument('bag', help='a cut-off .mcap recording (no summary)')
    ap.add_argument('-o', '--output', default=None,
                    help='recovered file (default: <stem>_recovered.mcap beside the input)')
    a = ap.parse_args(argv)

    def body():
        print(format_recovery(recover(a.bag, a.output)))
        return 0
    return cli_errors('recover_bag', body)


if __name__ == '__main__':
    sys.exit(main())
