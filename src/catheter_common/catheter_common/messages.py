"""Conversions between the typed messages of catheter_interfaces and plain values or the core
objects (no rclpy: only the generated message classes).

- ``/slave/impedance``, ``/master/link/impedance``: `ImpedanceModel` <-> the dict of
  ``impedance_master.impedance.Impedance.to_fields()`` / ``Impedance.from_fields()``
  (`impedance_msg`, `impedance_fields`), the anchor ('anchor_x', ... 'anchor_r') included;
  `impedance_key` tells whether two messages carry the same model (stamp ignored);
- ``/catheter/tip_wrench`` estimate: `TipForceEstimate` from force + covariance + status +
  method (`tip_force_msg`) and back to plain values (`tip_force_values`);
- ``/master/command``: `MasterCommand` from position, velocity, acceleration, rotation
  (`master_command_msg`, `master_command_values`).

Units: SI (m, m/s, m/s^2, rad, N, N^2 for the covariance); frames: catheter_base for forces.
Stamps are a builtin_interfaces/Time or integer nanoseconds. Every builder refuses bad input
with a ValueError naming the argument (catheter_common.checks), so a non-finite number never
goes on the wire through these helpers.

    >>> msg = impedance_msg(model, stamp=clock.now().to_msg())       # model.to_fields()
    >>> Impedance.from_fields(impedance_fields(msg))                   # the same model
"""
from __future__ import annotations

import functools
import math
import operator
from typing import Dict, Mapping, Sequence, Tuple

from catheter_interfaces.msg import ImpedanceModel, TipForceEstimate

from catheter_common.checks import finite, nonneg
from catheter_common.topics import FRAME_CATHETER_BASE

#: TipForceEstimate.status values by lower-case name (read from the message's constants, so a
#: status added to the .msg is known here too)
TIP_FORCE_STATUS = {name.lower(): int(getattr(TipForceEstimate, name))
                    for name in dir(TipForceEstimate)
                    if name.isupper() and isinstance(getattr(TipForceEstimate, name), int)}
#: TipForceEstimate.method values
TIP_FORCE_METHODS = ('svr', 'mlp', 'fam', 'fam_fallback')
#: the tabulated model's node values: to_fields() prefix -> ImpedanceModel field
TABLES = (('S', 's_table'), ('F', 'f_table'), ('B', 'b_table'), ('C', 'c_table'))
#: scalar fields of a table model carried besides the base fields
TABLE_SCALARS = ('x0', 'dx', 'sigma', 'v_s', 'beta')
#: ImpedanceModel.kind values
KIND_LINEAR, KIND_TABLE = int(ImpedanceModel.KIND_LINEAR), int(ImpedanceModel.KIND_TABLE)
#: the anchor's fields, in message order: the same names in Impedance.to_fields() and in the
#: message (read from the .msg, the one place they are defined: 'anchor_x', ..., 'anchor_r')
ANCHOR_FIELDS = tuple(n for n in ImpedanceModel.get_fields_and_field_types()
                      if n.startswith('anchor_'))
#: the message fields that define the model (all but the header and the identifier's status
#: text, which Impedance.from_fields does not use): `impedance_key`
MODEL_FIELDS = tuple(n for n in ImpedanceModel.get_fields_and_field_types()
                     if n not in ('header', 'status'))
#: `impedance_key`'s tuple in one C call (a generator over the fields was 4 % of a lockstep
#: run's main process under cProfile: the identifier re-sends its model every period)
_model_getter = operator.attrgetter(*MODEL_FIELDS)
assert len(MODEL_FIELDS) > 1               # (one name: attrgetter returns no tuple)


def _finite_all(name, values) -> list:
    """`values` as a list of floats; ValueError naming the first that is not finite, as
    ``name(i)`` (one C-level pass when all are fine: the 1 kHz models carry ~70 numbers)."""
    if type(values).__name__ == 'array' and values.typecode == 'd':   # a message's float64[]
        if all(map(math.isfinite, values)):
            return values.tolist()
    values = list(values)
    try:
        out = [float(v) for v in values]
        ok = all(map(math.isfinite, out))
    except (TypeError, ValueError):
        ok = False
    if not ok:
        for i, v in enumerate(values):
            finite(name(i), v)
    return out


def stamp_msg(stamp=None):
    """A builtin_interfaces/Time from a Time, integer nanoseconds >= 0, or None (zero)."""
    from builtin_interfaces.msg import Time
    if stamp is None:
        return Time()
    if isinstance(stamp, Time):
        return stamp
    if isinstance(stamp, bool) or not isinstance(stamp, int) or stamp < 0:
        raise ValueError(f'stamp must be a builtin_interfaces/Time or int nanoseconds >= 0, '
                         f'got {stamp!r}')
    return Time(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000)


def stamp_ns(msg) -> int:
    """The header stamp of ``msg`` in integer nanoseconds."""
    s = msg.header.stamp
    return int(s.sec) * 1_000_000_000 + int(s.nanosec)


def _header(stamp, frame_id: str):
    from std_msgs.msg import Header
    if not isinstance(frame_id, str):
        raise ValueError(f'frame_id must be a string, got {frame_id!r}')
    return Header(stamp=stamp_msg(stamp), frame_id=frame_id)


# ------------------------------------------------------------------ impedance model
def impedance_msg(model, stamp=None, frame_id: str = ''):
    """An ImpedanceModel message from ``model``: an object with ``to_fields()`` (and optionally
    ``status``), or such a dict of fields ('m', 'c', 'k', 'offset', 'valid', 'kind' and, for
    tables, 'x0', 'dx', 'sigma', 'v_s', 'beta', 'n', 'S0'.., 'F0'.., 'B0'.., 'C0'..).
    Keys this message does not know are not carried."""
    if isinstance(model, Mapping):
        fields = model
        status = fields.get('status', '')
    elif callable(getattr(model, 'to_fields', None)):
        fields = model.to_fields()
        status = getattr(model, 'status', '')
    else:
        raise ValueError(f'model must have to_fields() or be a dict of fields, got '
                         f'{type(model).__name__}')
    for name in ('m', 'c', 'k', 'offset', 'valid'):
        if name not in fields:
            raise ValueError(f'model is missing the field {name!r}')
    if not isinstance(status, str):
        raise ValueError(f'model status must be a string, got {status!r}')
    msg = ImpedanceModel(header=_header(stamp, frame_id), status=status)
    kind = int(round(finite('model kind', fields.get('kind', KIND_LINEAR))))
    if kind not in (KIND_LINEAR, KIND_TABLE):
        raise ValueError(f'model kind must be 0 (linear) or 1 (table), got {kind}')
    msg.kind = kind
    msg.m = finite('model m', fields['m'])
    msg.c = finite('model c', fields['c'])
    msg.k = finite('model k', fields['k'])
    msg.offset = finite('model offset', fields['offset'])
    msg.valid = finite('model valid', fields['valid']) > 0.5
    if kind == KIND_TABLE:
        for name in TABLE_SCALARS + ('n',):
            if name not in fields:
                raise ValueError(f'model is missing the field {name!r} (table model)')
        n = int(round(finite('model n', fields['n'])))
        if n < 2:
            raise ValueError(f'model n must be >= 2 for a table model, got {fields["n"]!r}')
        for name in TABLE_SCALARS:
            setattr(msg, name, finite(f'model {name}', fields[name]))
        for prefix, attr in TABLES:
            keys = [f'{prefix}{i}' for i in range(n)]
            missing = [k for k in keys if k not in fields]
            if missing:
                raise ValueError(f'model is missing the field {missing[0]!r} (table model)')
            setattr(msg, attr, _finite_all(lambda i, p=prefix: f'model {p}{i}',
                                           [fields[k] for k in keys]))
    else:
        for name in ('sigma', 'v_s', 'beta'):
            value = getattr(model, name, None) if not isinstance(model, Mapping) \
                else fields.get(name)
            if value is not None:
                setattr(msg, name, finite(f'model {name}', value))
    present = [n for n in ANCHOR_FIELDS if n in fields]
    if present:
        if len(present) != len(ANCHOR_FIELDS):
            missing = [n for n in ANCHOR_FIELDS if n not in fields]
            raise ValueError(f'model is missing the field {missing[0]!r} (anchored model)')
        msg.has_anchor = True
        for name in ANCHOR_FIELDS:
            setattr(msg, name, finite(f'model {name}', fields[name]))
    return msg


def impedance_fields(msg) -> Dict[str, float]:
    """The ``Impedance.to_fields()`` dict carried by an ImpedanceModel message (its inverse:
    ``Impedance.from_fields(impedance_fields(msg))``). ValueError naming the field when the
    message is inconsistent (unknown kind, tables of different lengths, tables in a linear
    model, a non-finite value in ANY field, used or not)."""
    kind = int(msg.kind)
    if kind not in (KIND_LINEAR, KIND_TABLE):
        raise ValueError(f'msg.kind must be 0 (linear) or 1 (table), got {kind}')
    d = {'m': finite('msg.m', msg.m), 'c': finite('msg.c', msg.c),
         'k': finite('msg.k', msg.k), 'offset': finite('msg.offset', msg.offset),
         'valid': 1.0 if msg.valid else 0.0, 'kind': float(kind)}
    # every number of the message is finite, used or not: a relay passes on only messages
    # that hold no NaN anywhere
    scalars = dict(zip(TABLE_SCALARS, _finite_all(lambda i: f'msg.{TABLE_SCALARS[i]}',
                                                  [getattr(msg, n) for n in TABLE_SCALARS]),
                       strict=True))
    anchor = _finite_all(lambda i: f'msg.{ANCHOR_FIELDS[i]}',
                         [getattr(msg, n) for n in ANCHOR_FIELDS])
    if msg.has_anchor:
        d.update(zip(ANCHOR_FIELDS, anchor, strict=True))
    if kind == KIND_LINEAR:
        for _, attr in TABLES:
            if len(getattr(msg, attr)):
                raise ValueError(f'msg.{attr} must be empty for a linear model (kind 0), got '
                                 f'{len(getattr(msg, attr))} nodes')
        return d
    tables = [getattr(msg, attr) for _, attr in TABLES]
    n = len(tables[0])
    if n < 2:
        raise ValueError(f'msg.s_table must have >= 2 nodes for a table model, got {n}')
    for (_, attr), t in zip(TABLES, tables, strict=True):
        if len(t) != n:
            raise ValueError(f'msg.{attr} must have {n} nodes like s_table, got {len(t)}')
    d.update(scalars)
    d['n'] = float(n)
    for (prefix, attr), t in zip(TABLES, tables, strict=True):
        d.update(zip(_table_keys(prefix, n), _finite_all(lambda i, a=attr: f'msg.{a}[{i}]', t),
                     strict=True))
    return d


@functools.lru_cache(maxsize=64)
def _table_keys(prefix: str, n: int) -> Tuple[str, ...]:
    """('S0', 'S1', ...): the to_fields() names of a table's n nodes."""
    return tuple(f'{prefix}{i}' for i in range(n))


def impedance_key(msg) -> tuple:
    """The model an ImpedanceModel carries, as a comparable tuple (`MODEL_FIELDS`: every
    field but the header and the status text): equal keys, the same model (an identifier
    re-sending a held model)."""
    return _model_getter(msg)


# ------------------------------------------------------------------ tip force estimate
def _status_code(status) -> int:
    if isinstance(status, str):
        if status.lower() not in TIP_FORCE_STATUS:
            raise ValueError(f'status must be one of {sorted(TIP_FORCE_STATUS)}, got {status!r}')
        return TIP_FORCE_STATUS[status.lower()]
    if isinstance(status, bool) or not isinstance(status, int) \
            or status not in TIP_FORCE_STATUS.values():
        raise ValueError(f'status must be one of {sorted(TIP_FORCE_STATUS.values())} or '
                         f'{sorted(TIP_FORCE_STATUS)}, got {status!r}')
    return status


def tip_force_msg(force: Sequence[float], covariance=None, status='ok', method: str = 'svr',
                  domain_distance: float = 0.0, stamp=None,
                  frame_id: str = FRAME_CATHETER_BASE):
    """A TipForceEstimate message.

    ``force``: (fx, fy) or (fx, fy, fz) N in catheter_base; ``covariance``: 2x2 (or 4 values
    row-major) N^2 over (fx, fy), symmetric with a non-negative diagonal, or None (unknown:
    [-1, 0, 0, -1], the sensor_msgs convention of a negative first element); ``status``: a
    name of TIP_FORCE_STATUS or its code; ``method``: one of TIP_FORCE_METHODS;
    ``domain_distance``: >= 0 (0 inside the estimator's domain).
    """
    from geometry_msgs.msg import Vector3
    try:
        f = [float(v) for v in force]
    except (TypeError, ValueError):
        raise ValueError(f'force must be 2 or 3 numbers, got {force!r}') from None
    if len(f) not in (2, 3):
        raise ValueError(f'force must be 2 or 3 numbers, got {len(f)}')
    f = [finite(f'force[{i}]', v) for i, v in enumerate(f)] + [0.0] * (3 - len(f))
    if covariance is None:
        cov = [-1.0, 0.0, 0.0, -1.0]
    else:
        try:
            rows = list(covariance)
            flat = [v for r in rows for v in r] if len(rows) == 2 else rows
            flat = [float(v) for v in flat]
        except (TypeError, ValueError):
            raise ValueError(f'covariance must be 2x2 or 4 numbers, got {covariance!r}') \
                from None
        if len(flat) != 4:
            raise ValueError(f'covariance must be 2x2 or 4 numbers, got {len(flat)} values')
        cov = [finite(f'covariance[{i}]', v) for i, v in enumerate(flat)]
        if cov[0] < 0 or cov[3] < 0:
            raise ValueError(f'covariance diagonal must be >= 0, got {cov[0]}, {cov[3]}')
        if abs(cov[1] - cov[2]) > 1e-12 * max(1.0, abs(cov[1]), abs(cov[2])):
            raise ValueError(f'covariance must be symmetric, got {cov[1]} and {cov[2]}')
    if method not in TIP_FORCE_METHODS:
        raise ValueError(f'method must be one of {TIP_FORCE_METHODS}, got {method!r}')
    return TipForceEstimate(header=_header(stamp, frame_id),
                            force=Vector3(x=f[0], y=f[1], z=f[2]), covariance=cov,
                            status=_status_code(status), method=method,
                            domain_distance=nonneg('domain_distance', domain_distance))


def tip_force_values(msg) -> dict:
    """Plain values of a TipForceEstimate: force (fx, fy, fz) N, covariance ((2, 2) nested
    tuples, or None when unknown), status (code), status_name, method, domain_distance,
    stamp_ns, frame_id."""
    names = {v: k for k, v in TIP_FORCE_STATUS.items()}
    c = [float(v) for v in msg.covariance]
    return {'force': (float(msg.force.x), float(msg.force.y), float(msg.force.z)),
            'covariance': None if c[0] < 0 else ((c[0], c[1]), (c[2], c[3])),
            'status': int(msg.status), 'status_name': names.get(int(msg.status), 'unknown'),
            'method': str(msg.method), 'domain_distance': float(msg.domain_distance),
            'stamp_ns': stamp_ns(msg), 'frame_id': msg.header.frame_id}


# ------------------------------------------------------------------ master command
def master_command_msg(position: float, velocity: float, acceleration: float = 0.0,
                       rotation: float = 0.0, stamp=None, frame_id: str = ''):
    """A MasterCommand: insertion position m, velocity m/s, acceleration m/s^2, rotation rad
    (the checks of `catheter_common.outgoing.CommandOut`, which the 1 kHz publisher reuses)."""
    from catheter_common.outgoing import CommandOut
    header = _header(stamp, frame_id)
    msg = CommandOut(frame_id).fill(0, position, velocity, acceleration, rotation)
    msg.header = header
    return msg


def master_command_values(msg) -> Tuple[float, float, float, float]:
    """(position m, velocity m/s, acceleration m/s^2, rotation rad) of a MasterCommand;
    ValueError naming the field if one is not finite."""
    out = (msg.position, msg.velocity, msg.acceleration, msg.rotation)
    if type(out[0]) is float and type(out[1]) is float and type(out[2]) is float \
            and type(out[3]) is float and all(map(math.isfinite, out)):
        return out          # the 1 kHz path: a delivered message's fields are floats
    return tuple(finite(f'msg.{name}', getattr(msg, name))
                 for name in ('position', 'velocity', 'acceleration', 'rotation'))


__all__ = ['TIP_FORCE_STATUS', 'TIP_FORCE_METHODS', 'KIND_LINEAR', 'KIND_TABLE', 'ANCHOR_FIELDS',
           'stamp_msg', 'stamp_ns', 'impedance_msg', 'impedance_fields', 'impedance_key',
           'tip_force_msg', 'tip_force_values',
           'master_command_msg', 'master_command_values']
