"""catheter_common.messages: the typed messages of catheter_interfaces <-> core objects and
plain values, through real serialisation; and recordings of them decoded by rosbags (typestore
built from the MCAP's own schema text) and mcap_ros2."""
import math
import pathlib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rclpy.serialization import deserialize_message, serialize_message

from catheter_common import messages as M
from catheter_interfaces.msg import ImpedanceModel, MasterCommand, TipForceEstimate

impedance = pytest.importorskip('impedance_master.impedance')
Impedance = impedance.Impedance

FIN = st.floats(-1e6, 1e6, allow_nan=False)
POS = st.floats(1e-6, 1e3, allow_nan=False)


@st.composite
def models(draw):
    base = dict(m=draw(FIN), c=draw(FIN), k=draw(FIN), offset=draw(FIN),
                valid=draw(st.booleans()), status=draw(st.sampled_from(['ok', 'held', ''])),
                anchor=draw(st.none() | st.lists(FIN, min_size=7, max_size=7)))
    if draw(st.booleans()):
        return Impedance(**base)
    n = draw(st.integers(2, 40))
    tables = {name: draw(st.lists(FIN, min_size=n, max_size=n)) for name in 'SFBC'}
    return Impedance(**base, x0=draw(FIN), dx=draw(POS), sigma=draw(POS), v_s=draw(POS),
                     beta=draw(st.floats(0, 10)), **tables)


def _wire(msg):
    return deserialize_message(serialize_message(msg), type(msg))


@settings(max_examples=60, deadline=None)
@given(models(), st.integers(0, 2 ** 40))
def test_impedance_round_trip_through_the_wire(model, t_ns):
    msg = _wire(M.impedance_msg(model, stamp=t_ns, frame_id='catheter_base'))
    assert M.stamp_ns(msg) == t_ns and msg.status == model.status
    assert msg.kind == model.kind
    assert msg.has_anchor == (model.anchor is not None)
    fields = M.impedance_fields(msg)
    assert fields == model.to_fields()
    back = Impedance.from_fields(fields)
    for x, xd, xdd in ((0.0, 0.0, 0.0), (0.031, 0.02, -0.5), (0.2, -0.04, 1.0)):
        assert back.force(x, xd, xdd) == model.force(x, xd, xdd)


def test_the_anchor_travels_field_by_field_and_is_the_cores_anchor():
    """The message's anchor_* fields are the core's ANCHOR_FIELDS (one definition each side,
    equal), each value lands in its own field, and a partial anchor is refused."""
    assert M.ANCHOR_FIELDS == impedance.ANCHOR_FIELDS
    vals = (0.031, 0.012, -0.4, 0.9, 1.2, 0.25, -0.01)
    model = Impedance(0.1, 2.0, 3.0, 0.5, True, anchor=vals)
    msg = _wire(M.impedance_msg(model))
    assert msg.has_anchor
    assert tuple(getattr(msg, n) for n in M.ANCHOR_FIELDS) == vals
    assert Impedance.from_fields(M.impedance_fields(msg)).anchor == model.anchor
    plain = _wire(M.impedance_msg(Impedance(0.1, 2.0, 3.0, 0.5)))
    assert not plain.has_anchor and 'anchor_x' not in M.impedance_fields(plain)
    fields = model.to_fields()
    del fields['anchor_r']
    with pytest.raises(ValueError, match='anchor_r'):
        M.impedance_msg(fields)
    msg.anchor_f = math.nan
    with pytest.raises(ValueError, match='anchor_f'):
        M.impedance_fields(msg)


def test_impedance_key_ignores_stamp_and_status_but_not_the_model():
    a = Impedance(0.1, 2.0, 3.0, 0.5, True, x0=0.01, dx=0.005, S=[1, 2], F=[4, 5],
                  B=[7, 8], C=[10, 11], status='ok', anchor=(0, 0, 0, 0, 0, 0.1, 0))
    key = M.impedance_key(M.impedance_msg(a, stamp=5))
    assert M.impedance_key(M.impedance_msg(a.copy(status='at_rest'), stamp=9)) == key
    for change in (dict(c=2.5), dict(valid=False), dict(C=[10, 11.5]),
                   dict(anchor=(0, 0, 0, 0, 0, 0.2, 0)), dict(anchor=None), dict(sigma=1e-4)):
        assert M.impedance_key(M.impedance_msg(a.copy(**change))) != key, change


def test_impedance_key_sees_every_model_field():
    """Each field of MODEL_FIELDS changed alone on the message changes the key (the key is
    read in one attrgetter: a field left out would take a changed model for the held one)."""
    import array
    a = Impedance(0.1, 2.0, 3.0, 0.5, True, x0=0.01, dx=0.005, S=[1, 2], F=[4, 5],
                  B=[7, 8], C=[10, 11], status='ok', anchor=(0, 0, 0, 0, 0, 0.1, 0))
    key = M.impedance_key(M.impedance_msg(a, stamp=5))
    assert len(key) == len(M.MODEL_FIELDS)
    for name in M.MODEL_FIELDS:
        msg = M.impedance_msg(a, stamp=5)
        v = getattr(msg, name)
        if isinstance(v, bool):
            new = not v
        elif isinstance(v, int):
            new = 1 - v if v in (0, 1) else v + 1
        elif isinstance(v, float):
            new = v + 0.5
        else:
            new = array.array('d', list(v) + [99.0])
        setattr(msg, name, new)
        assert M.impedance_key(msg) != key, name


@pytest.mark.parametrize('field', ['x0', 'dx', 'sigma', 'v_s', 'beta', 'anchor_x', 'anchor_r'])
def test_a_non_finite_unused_field_is_refused_too(field):
    """A relay passes on only clean messages: NaN in a field a linear model does not use
    (found by the node fuzz: sim_haptic_node relayed x0 = NaN to the master)."""
    msg = M.impedance_msg(Impedance(0.1, 2.0, 3.0, 0.5))
    setattr(msg, field, math.nan)
    with pytest.raises(ValueError, match=f'msg\\.{field}'):
        M.impedance_fields(msg)


def test_tables_in_a_linear_model_are_refused():
    msg = M.impedance_msg(Impedance(0.1, 2.0, 3.0, 0.5))
    msg.c_table = [1.0, 2.0]
    with pytest.raises(ValueError, match='c_table'):
        M.impedance_fields(msg)


def test_a_bad_table_value_is_named_by_its_index():
    msg = M.impedance_msg(Impedance(0.1, 2.0, 3.0, 0.5, True, x0=0.01, dx=0.005,
                                    S=[1, 2, 3], F=[4, 5, 6], B=[7, 8, 9], C=[1, 2, 3]))
    msg.f_table[2] = math.inf
    with pytest.raises(ValueError, match=r'msg\.f_table\[2\]'):
        M.impedance_fields(msg)


def test_impedance_table_fields_land_in_the_named_arrays():
    model = Impedance(0.1, 2.0, 3.0, 0.5, True, x0=0.01, dx=0.005, S=[1, 2, 3], F=[4, 5, 6],
                      B=[7, 8, 9], C=[10, 11, 12], status='ok')
    msg = M.impedance_msg(model)
    assert msg.kind == ImpedanceModel.KIND_TABLE
    assert list(msg.s_table) == [1, 2, 3] and list(msg.c_table) == [10, 11, 12]
    assert list(msg.f_table) == [4, 5, 6] and list(msg.b_table) == [7, 8, 9]
    assert (msg.x0, msg.dx, msg.valid) == (0.01, 0.005, True)
    linear = M.impedance_msg(Impedance(1.0, 2.0, 3.0, 4.0, False))
    assert linear.kind == ImpedanceModel.KIND_LINEAR and len(linear.s_table) == 0
    assert not linear.valid


def test_impedance_bad_input_is_refused_naming_the_field():
    good = Impedance(0.1, 2.0, 3.0, 0.5, True, S=[1, 2], F=[1, 2], B=[1, 2], C=[1, 2])
    fields = good.to_fields()
    for key, value, match in (('m', math.nan, 'model m'), ('kind', 7.0, 'kind'),
                              ('S1', math.inf, 'model S1'), ('n', 1.0, 'model n')):
        bad = dict(fields, **{key: value})
        with pytest.raises(ValueError, match=match):
            M.impedance_msg(bad)
    with pytest.raises(ValueError, match="missing the field 'F1'"):
        M.impedance_msg({k: v for k, v in fields.items() if k != 'F1'})
    with pytest.raises(ValueError, match="missing the field 'valid'"):
        M.impedance_msg({'m': 0.0, 'c': 0.0, 'k': 0.0, 'offset': 0.0})
    with pytest.raises(ValueError, match='model must'):
        M.impedance_msg(42)
    msg = M.impedance_msg(good)
    msg.f_table = [1.0]
    with pytest.raises(ValueError, match='msg.f_table'):
        M.impedance_fields(msg)
    msg = M.impedance_msg(good)
    msg.c = math.nan
    with pytest.raises(ValueError, match='msg.c'):
        M.impedance_fields(msg)
    msg.c, msg.kind = 0.0, 5
    with pytest.raises(ValueError, match='msg.kind'):
        M.impedance_fields(msg)
    with pytest.raises(ValueError, match='stamp'):
        M.impedance_msg(good, stamp=-1)
    with pytest.raises(ValueError, match='stamp'):
        M.impedance_msg(good, stamp=1.5)


@settings(max_examples=40, deadline=None)
@given(st.lists(FIN, min_size=2, max_size=3), st.floats(0, 10), st.floats(0, 10),
       st.floats(-1, 1), st.sampled_from(sorted(M.TIP_FORCE_STATUS)),
       st.sampled_from(M.TIP_FORCE_METHODS), st.floats(0, 100))
def test_tip_force_round_trip(force, vx, vy, rho, status, method, dist):
    cxy = rho * math.sqrt(vx * vy)
    cov = [[vx, cxy], [cxy, vy]]
    msg = _wire(M.tip_force_msg(force, cov, status, method, dist, stamp=123))
    v = M.tip_force_values(msg)
    assert v['force'] == tuple(force + [0.0] * (3 - len(force)))
    assert v['covariance'] == ((vx, cxy), (cxy, vy))
    assert v['status'] == getattr(TipForceEstimate, status.upper())
    assert v['status_name'] == status and v['method'] == method
    assert v['domain_distance'] == dist and v['stamp_ns'] == 123
    assert v['frame_id'] == 'catheter_base'


def test_tip_force_statuses_are_the_message_constants_and_bad_input_is_refused():
    assert M.TIP_FORCE_STATUS == {'ok': 0, 'out_of_domain': 1, 'non_finite_input': 2,
                                  'no_shape': 3, 'unobservable_axial': 4}
    assert M.tip_force_values(M.tip_force_msg((0.1, 0.2)))['covariance'] is None
    assert M.tip_force_msg((0, 0), status=TipForceEstimate.NO_SHAPE).status == 3
    for kwargs, match in (({'force': (math.nan, 0.0)}, r'force\[0\]'),
                          ({'force': (1.0,)}, 'force'),
                          ({'force': 'ab'}, 'force'),
                          ({'covariance': [[1, 2], [3, 4]]}, 'symmetric'),
                          ({'covariance': [[-1, 0], [0, 1]]}, 'diagonal'),
                          ({'covariance': [1, 0, 0]}, 'covariance'),
                          ({'covariance': [[1, 0], [0, math.inf]]}, r'covariance\[3\]'),
                          ({'status': 'bogus'}, 'status'), ({'status': 9}, 'status'),
                          ({'method': 'bogus'}, 'method'),
                          ({'domain_distance': -1.0}, 'domain_distance')):
        kw = {'force': (0.1, 0.2)}
        kw.update(kwargs)
        with pytest.raises(ValueError, match=match):
            M.tip_force_msg(**kw)


@settings(max_examples=30, deadline=None)
@given(FIN, FIN, FIN, FIN)
def test_master_command_round_trip(x, v, a, r):
    msg = _wire(M.master_command_msg(x, v, a, r, stamp=5_000_000_001))
    assert M.master_command_values(msg) == (x, v, a, r)
    assert msg.header.stamp.sec == 5 and msg.header.stamp.nanosec == 1


def test_master_command_refuses_non_finite():
    with pytest.raises(ValueError, match='acceleration'):
        M.master_command_msg(0.0, 0.0, math.inf)
    msg = MasterCommand(position=math.nan)
    with pytest.raises(ValueError, match='msg.position'):
        M.master_command_values(msg)


def test_recorded_typed_messages_decode_from_the_mcap_schema_text(tmp_path):
    """The recorder stores the custom definitions as schemas: rosbags with a typestore built
    from the file's own schema text, and mcap_ros2, decode every message."""
    from mcap.reader import make_reader
    from mcap_ros2.reader import read_ros2_messages
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg
    from catheter_bringup.recorder import McapRecorder

    model = Impedance(0.1, 2.0, 3.0, 0.5, True, x0=0.01, dx=0.005, S=[1, 2, 3], F=[4, 5, 6],
                      B=[7, 8, 9], C=[10, 11, 12], status='ok')
    sent = {'/slave/impedance': M.impedance_msg(model, stamp=1),
            '/catheter/tip_estimate': M.tip_force_msg((0.1, -0.2), [[1e-4, 0], [0, 2e-4]],
                                                      'out_of_domain', 'mlp', 0.3, stamp=2),
            '/master/command': M.master_command_msg(0.01, 0.02, -0.3, 0.0, stamp=3)}
    path = tmp_path / 'typed.mcap'
    rec = McapRecorder(path)
    for i, (topic, msg) in enumerate(sent.items()):
        rec.add_topic(topic, f'catheter_interfaces/msg/{type(msg).__name__}')
        rec.write(topic, serialize_message(msg), i)
    rec.close()

    store = get_typestore(Stores.ROS2_JAZZY)
    with open(path, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        for schema in summary.schemas.values():
            assert schema.name.startswith('catheter_interfaces/msg/')
            assert 'MSG: std_msgs/Header' in schema.data.decode()
            store.register(get_types_from_msg(schema.data.decode(), schema.name))
        got = {c.topic: store.deserialize_cdr(m.data, summary.schemas[c.schema_id].name)
               for _, c, m in reader.iter_messages()}
    imp = got['/slave/impedance']
    assert imp.KIND_TABLE == 1 and imp.kind == 1 and list(imp.b_table) == [7, 8, 9]
    assert imp.status == 'ok' and imp.valid
    est = got['/catheter/tip_estimate']
    assert est.status == est.OUT_OF_DOMAIN and est.method == 'mlp'
    assert list(est.covariance) == [1e-4, 0, 0, 2e-4] and est.force.y == -0.2
    assert got['/master/command'].acceleration == -0.3

    decoded = {m.channel.topic: m.ros_msg for m in read_ros2_messages(str(path))}
    assert list(decoded['/slave/impedance'].c_table) == [10, 11, 12]
    assert decoded['/catheter/tip_estimate'].domain_distance == 0.3
    assert decoded['/master/command'].position == 0.01
    assert pathlib.Path(path).stat().st_size > 0
