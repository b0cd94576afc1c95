"""The reference runs kept in bags/reference/: `analyze` reproduces their recorded metrics, and
the files are what they say they are (readable by rosbags, complete, small)."""
import json
import math
import pathlib

import pytest

from catheter_bringup.analyze import _jsonable, analyze
from catheter_bringup.recorder import read_run_metadata

REF = pathlib.Path(__file__).resolve().parents[2] / 'bags' / 'reference'
BAGS = sorted(REF.glob('*.mcap'))


def _close(a, b, path='$'):
    if isinstance(a, dict):
        assert set(a) == set(b), f'{path}: keys {sorted(set(a) ^ set(b))}'
        for k in a:
            _close(a[k], b[k], f'{path}.{k}')
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _close(x, y, f'{path}[{i}]')
    elif isinstance(a, float) or isinstance(b, float):
        assert a is not None and b is not None, f'{path}: {a} vs {b}'
        assert math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), f'{path}: {a} vs {b}'
    else:
        assert a == b, f'{path}: {a!r} vs {b!r}'


def test_there_are_small_reference_runs():
    assert len(BAGS) >= 2
    assert sum(p.stat().st_size for p in BAGS) < 400_000


@pytest.mark.parametrize('bag', BAGS, ids=[p.stem for p in BAGS])
def test_analyze_reproduces_recorded_metrics(bag):
    stored = json.loads(bag.with_suffix('.json').read_text())
    _close(_jsonable(analyze(bag)), stored)
    assert stored['force_tracking']['ima']['all']['n'] > 0
    assert stored['force_tracking']['dfr']['all']['n'] > 0


@pytest.mark.parametrize('bag', BAGS, ids=[p.stem for p in BAGS])
def test_reference_run_is_complete_and_rosbags_reads_it(bag):
    meta = read_run_metadata(bag)
    assert meta['status'] == 'complete'
    counts = json.loads(meta['counts'])
    from rosbags.highlevel import AnyReader
    with AnyReader([bag]) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == counts
        c = next(c for c in reader.connections if c.topic == '/slave/force')
        first = next(reader.messages([c]))
        msg = reader.deserialize(first[2], c.msgtype)
        assert msg.header.frame_id == 'catheter_base'
