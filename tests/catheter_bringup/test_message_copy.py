"""`msg_copy.message_copier`: the worker bus's copy of a published message for its
in-process subscribers. The reference is rclpy's own round trip, deserialize_message(
serialize_message(msg)): the copy must equal it field for field AND in each value's Python
type (float / int / bool / str, array.array typecode, numpy dtype), for any message of every
type of the graph (hypothesis), and share no mutable object with the original (the nodes
reuse their outgoing messages; a subscriber may keep what it received)."""
import array
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from catheter_bringup import msg_copy as C
from catheter_bringup import rclpy_adapter as A
from catheter_bringup.cdr import message_class
from msg_tools import GRAPH_TYPES, message_strategy


def _typed(x):
    """A message or value as nested plain values, every leaf with its Python type (and an
    array's typecode, a numpy array's dtype)."""
    if hasattr(x, 'get_fields_and_field_types'):
        return (type(x).__name__, {k: _typed(getattr(x, k))
                                   for k in x.get_fields_and_field_types()})
    if isinstance(x, array.array):
        return ('array', x.typecode, [_leaf(v) for v in x])
    if isinstance(x, np.ndarray):
        return ('ndarray', str(x.dtype), [_leaf(v) for v in x.tolist()])
    if isinstance(x, list):
        return ('list', [_typed(v) for v in x])
    return _leaf(x)


def _leaf(v):
    if isinstance(v, float) and math.isnan(v):
        return ('float', 'nan')
    return (type(v).__name__, v)


def _mutables(x, out):
    """ids of every mutable object reachable from a message (messages, lists, arrays)."""
    if hasattr(x, 'get_fields_and_field_types'):
        out.add(id(x))
        for k in x.get_fields_and_field_types():
            _mutables(getattr(x, k), out)
    elif isinstance(x, (list, array.array, np.ndarray)):
        out.add(id(x))
        if isinstance(x, list):
            for v in x:
                _mutables(v, out)
    return out


def _check(msg):
    """True: copied, and the copy is the round trip's message; False: the copier refused it
    (None) and the caller deserialises."""
    ser, de = A.serializer()
    ref = de(ser(msg), type(msg))
    copier = C.message_copier(type(msg))
    got = copier(msg) if copier is not None else None
    if got is None:
        return False
    assert type(got) is type(msg)
    assert _typed(got) == _typed(ref)
    # (a message holding a NaN never equals another; `_typed` above compared it as 'nan')
    assert got == ref or 'nan' in _leaves(ref)
    assert not (_mutables(got, set()) & _mutables(msg, set()))
    # and the same message on the wire (the bytes themselves differ in CDR's alignment
    # padding, which serialize_message leaves uninitialised)
    assert _typed(de(ser(got), type(msg))) == _typed(ref)
    return True


def _leaves(x):
    t = _typed(x)
    stack, out = [t], []
    while stack:
        v = stack.pop()
        if isinstance(v, tuple) and len(v) == 2 and isinstance(v[0], str) and \
                not isinstance(v[1], (dict, list)):
            out.append(v[1])
        elif isinstance(v, tuple):
            stack.extend(v[1:])
        elif isinstance(v, dict):
            stack.extend(v.values())
        elif isinstance(v, list):
            stack.extend(v)
    return out


@pytest.mark.parametrize('type_name', GRAPH_TYPES)
def test_copy_equals_the_serialisation_round_trip(type_name):
    cls = message_class(type_name)
    copier = C.message_copier(cls)

    @settings(max_examples=40, deadline=None)
    @given(message_strategy(cls, max_len=5))
    def check(msg):
        assert _check(msg) is (copier is not None)
    check()


def test_the_graphs_1khz_types_are_copied_and_float32_ones_are_not():
    for name in ('geometry_msgs/msg/WrenchStamped', 'sensor_msgs/msg/JointState',
                 'catheter_interfaces/msg/MasterCommand',
                 'catheter_interfaces/msg/ImpedanceModel', 'sensor_msgs/msg/Image',
                 'geometry_msgs/msg/PoseArray'):
        assert C.message_copier(message_class(name)) is not None, name
    # a float32 scalar is rounded by the round trip: such a type is deserialised instead
    assert C.message_copier(message_class('std_msgs/msg/ColorRGBA')) is None
    assert C.message_copier(message_class('visualization_msgs/msg/Marker')) is None


@given(st.floats(allow_nan=True), st.integers(-2 ** 31, 2 ** 31 - 1), st.booleans())
@settings(max_examples=60, deadline=None)
def test_unchecked_fields_are_copied_only_when_exact(f, i, b):
    """With field checks off (rclpy's default) a node may leave an int in a double field (the
    round trip turns it into garbage: 3 -> 5e-324), a numpy scalar in a float or int field,
    a list in a double[] field (its setter converts that one). The copier refuses a message
    whose scalars are not of their field's exact type (the bus then deserialises, so the
    subscribers get what DDS and the recording carry) and copies the rest exactly."""
    from geometry_msgs.msg import WrenchStamped
    from sensor_msgs.msg import JointState
    from catheter_interfaces.msg import ImpedanceModel
    w = WrenchStamped(check_fields=False)
    w.wrench.force.x = f
    w.header.stamp.sec = i
    assert _check(w)
    w.wrench.force.y = 3                              # an int in a double field
    assert not _check(w)
    ser, de = A.serializer()
    assert de(ser(w), WrenchStamped).wrench.force.y != 3.0     # why: the trip garbles it
    w.wrench.force.y = np.float64(f)
    assert not _check(w)
    js = JointState(check_fields=False)
    js.position = [f, 1.0]                            # the setter makes it array('d')
    assert _check(js)
    m = ImpedanceModel(check_fields=False)
    m.valid = b
    m.s_table = [0.5, f]
    assert _check(m)
    m.kind = np.uint8(7)          # (rclpy's serializer aborts the process on this one)
    assert C.message_copier(ImpedanceModel)(m) is None
    assert C.message_copier(WrenchStamped)(JointState()) is None     # another class


def test_shared_copy_is_independent_of_a_reused_outgoing_message():
    """The publisher fills the same object again next period: the copy keeps the old values."""
    from sensor_msgs.msg import JointState
    js = JointState(name=['insertion'], position=[0.01], velocity=[0.0], effort=[0.5])
    got = C.message_copier(JointState)(js)
    js.position[0] = 0.02
    js.name[0] = 'x'
    js.header.stamp.sec = 9
    assert list(got.position) == [0.01] and got.name == ['insertion']
    assert got.header.stamp.sec == 0


@pytest.mark.ros
def test_immediate_bus_hands_subscribers_the_copy_made_at_publish(ros, monkeypatch):
    """A worker's bus: the subscriber gets the message as published even when the publisher
    refills the same object before delivery (a held delivery runs after the callback); a
    message the copier refuses is deserialised from the bytes instead (the subscriber gets
    what DDS and the recording carry)."""
    from geometry_msgs.msg import WrenchStamped
    from catheter_bringup.bus import LocalBus
    from catheter_common.qos import QOS_DEFAULT
    a, b = ros.node('copy_a'), ros.node('copy_b')
    pub = a.create_publisher(WrenchStamped, 'copy/w', QOS_DEFAULT)
    got = []
    b.create_subscription(WrenchStamped, 'copy/w', got.append, QOS_DEFAULT)
    bus = LocalBus(immediate=True)
    for n in (a, b):
        bus.wrap_publishers(n)
    for n in (a, b):
        bus.wrap_subscriptions(n)
    w = WrenchStamped()
    import catheter_bringup.bus as bus_mod
    ser0, de0 = A.serializer()
    deserialised = []

    def counting_de(data, cls):
        deserialised.append(cls)
        return de0(data, cls)
    monkeypatch.setattr(bus_mod, 'serializer', lambda: (ser0, counting_de))
    decoded = []                               # the bus's generated decoder (`cdr_decode`)
    real_decoder = bus_mod.decoder

    def counting_decoder(cls):
        d = real_decoder(cls)
        return None if d is None else (lambda data: decoded.append(cls) or d(data))
    monkeypatch.setattr(bus_mod, 'decoder', counting_decoder)

    def tick():
        for k in (1.0, 2.0):                   # one reused message, published twice
            w.wrench.force.x = k
            w.header.stamp.sec = int(k)
            pub.publish(w)
        w.wrench.force.x = 99.0
    bus.timed('copy_a', tick)
    assert [m.wrench.force.x for m in got] == [1.0, 2.0]
    assert [m.header.stamp.sec for m in got] == [1, 2]
    assert all(m is not w for m in got)
    assert deserialised == [] and decoded == []     # the copies, not the bytes
    ser, de = A.serializer()
    w2 = WrenchStamped(check_fields=False)
    w2.wrench.force.y = 3                      # refused by the copier: deserialised
    bus.timed('copy_a', lambda: pub.publish(w2))
    assert _typed(got[-1]) == _typed(de(ser(w2), WrenchStamped))
    assert got[-1].wrench.force.y != 3         # (what the bytes carry)
    # from the bytes: by the type's generated decoder (rclpy's deserialiser where none)
    assert decoded == [WrenchStamped] and deserialised == []


@pytest.mark.ros
@pytest.mark.slow
def test_lockstep_with_copies_records_what_deserialising_records(tmp_path):
    """The whole graph (Experiment II, 1 s, vision chain included) in lockstep, once with the
    bus deserialising what it delivers and once with copies (`LocalBus.copy`, the workers'
    setting): every recorded message decodes to the same fields, /diagnostics aside (its
    timing values differ between any two runs). A node that depended on what the copy does
    differently (a type, a shared object) would show here."""
    import collections
    from mcap.reader import make_reader
    from catheter_bringup.runner import ScenarioRunner
    from catheter_bringup.scenario import load_scenario
    from msg_tools import plain
    _, de = A.serializer()

    def run(copy, path):
        sc = load_scenario('experiment_ii')
        sc['duration'] = 1.0
        r = ScenarioRunner(sc, bag=str(path), progress=False, log=lambda *a: None)
        r.setup()
        r.bus.copy = copy
        assert r.run().status == 'complete'
        out = collections.defaultdict(list)
        with open(path, 'rb') as f:
            for schema, ch, msg in make_reader(f).iter_messages():
                if ch.topic != '/diagnostics':
                    out[ch.topic].append(plain(de(msg.data, message_class(schema.name))))
        return out
    a = run(False, tmp_path / 'deserialised.mcap')
    b = run(True, tmp_path / 'copied.mcap')
    assert set(a) == set(b) and len(a) >= 10
    assert '/camera/image_raw' in a and len(a['/master/command']) >= 900
    for topic in a:
        assert a[topic] == b[topic], topic
