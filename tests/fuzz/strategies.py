"""Hypothesis strategies for every message type the nodes take as input, and for runtime
parameter changes: plausible values mixed with what an attacker or a clumsy user sends
(NaN, +-inf, +-1e308, subnormals, huge finite values, empty and over-long sequences,
wrong frames, wrong encodings and sizes).

Drawing every float of every message through hypothesis costs 1-2 ms a message; the fuzz
needs thousands per topic. So hypothesis draws a *pool* of values (plausible and nasty) and
a seed, and a builder per message type makes each message from them (its lengths, which
pool values go where, encodings and sizes; a seeded share of plausible values, so that some
batches are mostly clean and reach deep into the nodes) with a `random.Random(seed)`: the
messages are a function of what hypothesis drew (it still shrinks the pool and the seed),
at ~30 us each.
`messages(builder)` is the strategy of single messages built this way.
"""
from __future__ import annotations

import math
import random

from geometry_msgs.msg import Point, Pose, PoseArray, WrenchStamped
from hypothesis import strategies as st
from sensor_msgs.msg import Image, JointState

from catheter_common.images import CHANNELS

#: values that break arithmetic
NASTY = [math.nan, math.inf, -math.inf, 1e308, -1e308, 1.7e308, -1.7e308, 5e-324, -5e-324,
         1e300, -1e300, 1e6, -1e6, 0.0, -0.0]


def unit_floats():
    """Mostly values in [-1, 1] (scaled by the builders), sometimes anything, sometimes nasty."""
    return st.one_of(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0),
                     st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(NASTY))


#: what hypothesis draws for a batch of messages: the value pool and the builders' seed
POOLS = st.tuples(st.lists(unit_floats(), min_size=6, max_size=16), st.integers(0, 2 ** 32 - 1))


class Pick:
    """Values for one batch: pool values, a plausible one scaled to `scale`, a nasty one
    taken as it is."""

    def __init__(self, pool, seed):
        self.pool = list(pool) or [0.0]
        self.r = random.Random(seed)
        #: share of values drawn plausibly (uniform in [-1, 1]) instead of from the pool
        self.clean = self.r.random()

    def value(self, scale: float = 1.0) -> float:
        r = self.r
        v = r.uniform(-1.0, 1.0) if r.random() < self.clean else \
            self.pool[r.randrange(len(self.pool))]
        return v * scale if -1.0 <= v <= 1.0 else v

    def values(self, scale: float, lengths=(0, 1, 2, 2, 2, 3, 4)):
        return [self.value(scale) for _ in range(self.r.choice(lengths))]

    def choice(self, xs):
        return self.r.choice(xs)


FRAMES = ['', 'catheter_base', 'catheter_base', 'camera_optical_frame', 'map', 'x' * 300]


def build_joint_state(p: Pick, scale: float = 0.1) -> JointState:
    """sensor_msgs/JointState with any lengths (independent per field) and values."""
    m = JointState()
    m.header.frame_id = p.choice(FRAMES)
    m.header.stamp.sec = p.r.randrange(2 ** 31)
    m.name = [p.choice(['insertion', 'rotation', '', 'x']) for _ in range(p.r.randrange(4))]
    m.position = p.values(scale)
    m.velocity = p.values(scale)
    m.effort = p.values(scale * 10)
    return m


def build_wrench(p: Pick, scale: float = 1.0) -> WrenchStamped:
    """geometry_msgs/WrenchStamped with any force / torque values and frames."""
    m = WrenchStamped()
    m.header.frame_id = p.choice(FRAMES)
    m.header.stamp.sec = p.r.randrange(2 ** 31)
    f, t = m.wrench.force, m.wrench.torque
    f.x, f.y, f.z = p.value(scale), p.value(scale), p.choice([0.0, 0.0, p.value(scale)])
    t.x, t.y = p.choice([0.0, 0.0, p.value(0.01)]), p.choice([0.0, 0.0, p.value(0.01)])
    t.z = p.value(scale * 0.01)
    return m


#: control points of a plausible 65 mm catheter (base -> tip), m
_CP = [(0.0, 0.0), (0.021, 0.0), (0.043, 0.002), (0.064, 0.006)]


def build_pose_array(p: Pick) -> PoseArray:
    """geometry_msgs/PoseArray: 0..6 poses, near a catheter's control points or anywhere."""
    m = PoseArray()
    m.header.frame_id = p.choice(['', 'catheter_base', 'catheter_base', 'catheter_base',
                                  'camera_optical_frame'])
    n = p.choice([4, 4, 4, 4, 4, 0, 1, 3, 5, 6])
    near = p.r.random() < 0.7
    for i in range(n):
        bx, by = _CP[i] if i < 4 else (0.07, 0.01)
        if near:                             # a catheter bent a little, in the training range
            x, y = bx + p.value(0.001) * i, by + p.value(0.004) * i * i
            z = p.choice([0.0, 0.0, 0.0, p.value(0.001)])
        else:
            x, y, z = p.value(0.1), p.value(0.1), p.value(0.1)
        m.poses.append(Pose(position=Point(x=x, y=y, z=z)))
    return m


def build_image(p: Pick, max_side: int = 48) -> Image:
    """sensor_msgs/Image: supported and unsupported encodings, sizes that match their data
    and sizes that do not (steps short or long, data too short), blank, striped or noise."""
    r = p.r
    m = Image()
    m.header.frame_id = p.choice(FRAMES)
    enc = p.choice(sorted(CHANNELS) + ['mono8', 'mono8', 'mono16', '32FC1', 'bayer_rggb8', ''])
    h, w = r.randrange(max_side + 1), r.randrange(max_side + 1)
    ch = CHANNELS.get(enc, 1)
    step = w * ch if r.random() < 0.8 else r.randrange(3 * max_side * 4)
    size = h * step if r.random() < 0.8 else r.randrange(h * step + 9)
    m.height, m.width, m.step, m.encoding = h, w, step, enc
    kind = r.choice(['blank', 'stripe', 'stripe', 'noise'])
    if kind == 'blank':
        data = bytes([r.randrange(256)]) * size
    elif kind == 'stripe':                   # a dark band across a bright frame
        row = max(step, 1)
        data = b''.join((bytes([20]) if 3 <= k % 16 < 6 else bytes([220])) * row
                        for k in range(size // row + 1))[:size]
    else:
        data = r.randbytes(size)
    m.data = data
    return m


_IMP_NAMES = ['m', 'c', 'k', 'offset', 'valid', 'kind', 'x0', 'dx', 'sigma', 'v_s', 'beta',
              'n', 'S0', 'S1', 'F0', 'F1', 'B0', 'B1', 'C0', 'C1', 'bogus', '']


def build_impedance(p: Pick) -> JointState:
    """sensor_msgs/JointState used as the impedance model's named values: well-formed linear
    and table models with any values, and malformed ones (missing or unknown names,
    name/position lengths that differ)."""
    m = JointState()
    form = p.choice(['linear', 'linear', 'linear', 'table', 'garbage'])
    if form == 'linear':
        names = ['m', 'c', 'k', 'offset', 'valid', 'kind']
        vals = [p.value(0.1), p.value(5.0), p.value(20.0), p.value(0.5),
                p.choice([1.0, 1.0, 1.0, 0.0, math.nan]), p.choice([0.0, 0.0, 0.0, 3.0])]
    elif form == 'table':
        n = p.choice([2, 3, 4])
        names = ['m', 'c', 'k', 'offset', 'valid', 'kind', 'x0', 'dx', 'sigma', 'v_s', 'beta',
                 'n']
        vals = [p.value(0.1), p.value(5.0), p.value(20.0), p.value(0.5), 1.0, 1.0,
                p.value(0.05), p.choice([0.005, 0.01, 0.0, -1.0]), 3e-4, 0.002, 0.5,
                float(p.choice([n, n, n + 1, 0]))]
        for t in 'SFBC':
            for i in range(n):
                names.append(f'{t}{i}')
                vals.append(p.value(1.0))
    else:
        names = [p.choice(_IMP_NAMES) for _ in range(p.r.randrange(9))]
        vals = p.values(10.0, lengths=range(10))
    m.name = names
    m.position = vals
    return m


BUILDERS = {'joint_state': build_joint_state, 'wrench': build_wrench,
            'pose_array': build_pose_array, 'image': build_image,
            'impedance': build_impedance}


def messages(builder, *args):
    """A strategy of single messages made by `builder` from a hypothesis-drawn pool."""
    return POOLS.map(lambda ps: builder(Pick(*ps), *args))


def param_values(spec):
    """Values for a parameter: valid ones of its type and range, and invalid ones."""
    d = spec.default
    if spec.choices is not None:
        good = st.sampled_from(list(spec.choices))
        bad = st.sampled_from(['bogus', 'III', 'foo', ''] if isinstance(d, str) else [0.5, 2.0])
    elif spec.numbers:
        lo = spec.lo if spec.lo is not None else -10.0
        hi = spec.hi if spec.hi is not None else 10.0
        good = st.lists(st.floats(lo, hi), min_size=spec.length, max_size=spec.length) \
            if spec.length else st.lists(st.floats(0.0, 5.0), min_size=2, max_size=2)
        bad = st.lists(st.floats(allow_nan=True), max_size=13)
    elif isinstance(d, bool):
        good = st.booleans()
        bad = st.just('yes')
    elif isinstance(d, int):
        good = st.integers(int(spec.lo), int(spec.hi)) if spec.lo is not None else st.integers()
        bad = st.integers(-2 ** 40, 2 ** 40)
    elif isinstance(d, float):
        good = st.floats(spec.lo, spec.hi) if spec.lo is not None else st.floats(-10, 10)
        bad = st.sampled_from(NASTY)
    else:
        good = st.just(d)
        bad = st.sampled_from(['/nonexistent/file.npz', 'bogus', ''])
    return st.one_of(good, good, bad)
