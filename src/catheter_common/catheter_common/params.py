"""Declared parameters that either apply at run time or say why not.

A node lists its parameters in a table of `Param` (name, default, description, range or
choices, whether it can change at run time, an optional check) and builds a `NodeParams`
from it. `NodeParams`:

- declares every parameter with a ParameterDescriptor (description, range, the allowed
  values in ``additional_constraints``, ``read_only`` for what cannot change at run time);
- refuses a start value it cannot use with a ValueError naming the parameter (an unknown
  choice, a non-finite number, an array of the wrong length, a file that does not load);
- registers an on-set callback: a runtime change of a ``dynamic`` parameter is validated the
  same way and handed to the node's ``apply(changes, values)`` hook, which builds what it
  needs and either takes it (the next callback or timer tick uses it: within one cycle) or
  raises ValueError, whose text is the refusal's reason; a change of anything else is refused
  (``read_only``);
- `seal(node)` also marks read-only every parameter the node declared outside its table
  (``declare()``, plain ``declare_parameter``), so no parameter is accepted and ignored.

`format_help` prints the table for ``<executable> --help`` without starting anything.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any, Callable, Dict, Iterable, Optional, Sequence, Tuple

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)

#: parameters rclpy itself declares and manages
_ROS_OWNED = ('use_sim_time', 'start_type_description_service')
_ATTR = '_catheter_params'


@dataclasses.dataclass(frozen=True)
class Param:
    """One declared parameter.

    name, default, description: as declared (the type is the default's type).
    lo, hi: inclusive range of a number (also applied to each element of ``numbers`` lists).
    choices: the allowed values (strings or numbers); anything else is refused.
    dynamic: True if the node applies a runtime change (its ``apply`` hook), False: read-only.
    check: callable(value) -> value or None (keep), raising ValueError with the reason: file
        parameters are loaded/validated here before they are accepted.
    numbers: the value is a list of numbers; ints and doubles are both accepted (YAML writes
        [51, 240] and [51.2, 240.0] differently) and returned as floats.
    length: required length of a list value (None: any).
    """
    name: str
    default: Any
    description: str
    lo: Optional[float] = None
    hi: Optional[float] = None
    choices: Optional[Tuple] = None
    dynamic: bool = False
    check: Optional[Callable[[Any], Any]] = None
    numbers: bool = False
    length: Optional[int] = None

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(description=self.description, read_only=not self.dynamic)
        notes = []
        if self.choices is not None:
            notes.append('one of: ' + ', '.join(str(c) for c in self.choices))
        if self.numbers:
            d.dynamic_typing = True
            if self.lo is not None or self.hi is not None:
                notes.append(f'each in [{self.lo}, {self.hi}]')
            if self.length is not None:
                notes.append(f'{self.length} numbers')
        elif self.lo is not None and self.hi is not None and not isinstance(self.default, bool):
            if isinstance(self.default, int):
                d.integer_range = [IntegerRange(from_value=int(self.lo), to_value=int(self.hi),
                                                step=1)]
            elif isinstance(self.default, float):
                d.floating_point_range = [FloatingPointRange(
                    from_value=float(self.lo), to_value=float(self.hi), step=0.0)]
        d.additional_constraints = '; '.join(notes)
        return d

    def validate(self, value):
        """The value as the node uses it, or ValueError naming the parameter."""
        name = self.name
        if self.numbers:
            try:
                out = [float(v) for v in value]
            except (TypeError, ValueError):
                raise ValueError(f'parameter {name} must be a list of numbers, got {value!r}') \
                    from None
            if not all(math.isfinite(v) for v in out):
                raise ValueError(f'parameter {name} has non-finite values: {out!r}')
            if self.length is not None and len(out) != self.length:
                raise ValueError(f'parameter {name} needs {self.length} values, got {len(out)}')
            for v in out:
                self._in_range(v)
            value = out
        elif isinstance(self.default, float) and not isinstance(value, bool):
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f'parameter {name} must be a finite number, got {value!r}')
            value = float(value)
            self._in_range(value)
        elif isinstance(self.default, int) and not isinstance(self.default, bool):
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(f'parameter {name} must be an integer, got {value!r}')
            self._in_range(value)
        elif isinstance(self.default, (list, tuple)) and self.length is not None:
            if len(value) != self.length:
                raise ValueError(f'parameter {name} needs {self.length} values, got '
                                 f'{len(value)}')
        if self.choices is not None and value not in self.choices:
            raise ValueError(f'parameter {name}={value!r} is not one of {list(self.choices)}')
        if self.check is not None:
            try:
                checked = self.check(value)
            except ValueError as exc:
                raise ValueError(f'parameter {name}={value!r}: {exc}') from None
            if checked is not None:
                value = checked
        return value

    def _in_range(self, v) -> None:
        if self.lo is not None and v < self.lo or self.hi is not None and v > self.hi:
            raise ValueError(f'parameter {self.name}={v!r} outside [{self.lo}, {self.hi}]')

    def help_line(self) -> str:
        kind = 'list' if self.numbers else type(self.default).__name__
        rng = ''
        if self.choices is not None:
            rng = ' {' + ' | '.join(str(c) for c in self.choices) + '}'
        elif self.lo is not None or self.hi is not None:
            rng = f' [{self.lo:g}, {self.hi:g}]' if isinstance(self.lo, (int, float)) and \
                isinstance(self.hi, (int, float)) else f' [{self.lo}, {self.hi}]'
        if self.length is not None:
            rng += f' ({self.length} values)'
        when = 'runtime' if self.dynamic else 'start only'
        return (f'  {self.name} ({kind}{rng}, default {self.default!r}, {when})\n'
                f'      {self.description}')


def table(*params: Param) -> Tuple[Param, ...]:
    """A parameter table: the given Params, names unique."""
    names = [p.name for p in params]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f'parameter table declares {dup} twice')
    return tuple(params)


def _fail(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)


class NodeParams:
    """The declared parameters of one node (see the module docstring).

    >>> self.params = NodeParams(self, PARAMS, apply=self._apply_params)
    >>> limit = self.params['limit']

    ``apply(changes, values)``: ``changes`` maps the changed names to their validated new
    values, ``values`` is every parameter after the change. It runs inside the set request:
    build whatever can fail first, then assign (raise ValueError to refuse, nothing changed).
    """

    def __init__(self, node, params: Sequence[Param],
                 apply: Optional[Callable[[Dict[str, Any], Dict[str, Any]], None]] = None):
        self._node = node
        self._specs: Dict[str, Param] = {p.name: p for p in table(*params)}
        if apply is None and any(p.dynamic for p in params):
            raise ValueError('a table with dynamic parameters needs an apply hook')
        self._apply = apply
        self.values: Dict[str, Any] = {}
        for p in params:
            value = node.declare_parameter(p.name, p.default, p.descriptor()).value
            self.values[p.name] = p.validate(value)
        reg = _registry(node)
        reg['dynamic'].update(p.name for p in params if p.dynamic)
        node.add_on_set_parameters_callback(self._on_set)

    def __getitem__(self, name: str):
        return self.values[name]

    def _on_set(self, params) -> SetParametersResult:
        node = self._node
        changes: Dict[str, Any] = {}
        for prm in params:
            spec = self._specs.get(prm.name)
            if spec is None:
                continue       # not ours: declared elsewhere (sealed read-only) or rclpy's own
            if not node.has_parameter(prm.name):
                continue       # being declared right now
            try:
                value = spec.validate(prm.value)
            except ValueError as exc:
                return _fail(str(exc))
            if value != self.values[prm.name]:
                changes[prm.name] = value      # (rclpy refuses read-only ones before this)
        if not changes:
            return SetParametersResult(successful=True)
        new = dict(self.values)
        new.update(changes)
        try:
            self._apply(changes, new)
        except ValueError as exc:
            return _fail(str(exc))
        self.values = new
        node.get_logger().info('parameters applied: ' + ', '.join(
            f'{k}={v!r}' for k, v in sorted(changes.items())))
        return SetParametersResult(successful=True)


def _registry(node) -> dict:
    reg = node.__dict__.get(_ATTR)
    if reg is None:
        reg = {'dynamic': set()}
        node.__dict__[_ATTR] = reg
    return reg


def declare(node, name: str, default, description: str, lo=None, hi=None,
            step=None, read_only: bool = True, choices=None):
    """Declare one parameter outside a table and return its value (refused with a
    ValueError naming it when not one of `choices`). Such a parameter cannot change at run
    time: nothing would apply it (`read_only` is kept for the older signature)."""
    spec = Param(name, default, description, lo=lo, hi=hi,
                 choices=tuple(choices) if choices is not None else None)
    value = node.declare_parameter(name, default, spec.descriptor()).value
    if choices is not None and value not in choices:
        raise ValueError(f'parameter {name}={value!r} is not one of {list(choices)}')
    return value


def seal(node) -> int:
    """Mark read-only every parameter of `node` that no table applies at run time (so a
    change is refused with a reason instead of accepted and ignored). Returns how many it
    changed. Idempotent."""
    dynamic = _registry(node)['dynamic']
    n = 0
    for name in node.list_parameters([], 0).names:
        if name in dynamic or name in _ROS_OWNED:
            continue
        desc = node.describe_parameter(name)
        if desc.read_only:
            continue
        desc = copy.deepcopy(desc)       # (describe_parameter returns the node's own object)
        desc.read_only = True
        node.set_descriptor(name, desc)
        n += 1
    return n


def format_help(executable: str, params: Iterable[Param], doc: str = '') -> str:
    """The text of `<executable> --help`: what the node does and its parameters."""
    lines = [f'usage: {executable} [--ros-args -p NAME:=VALUE ... -r FROM:=TO ...]', '']
    if doc:
        lines += [doc.strip(), '']
    params = list(params)
    if params:
        lines.append('parameters ("runtime": a change is applied within one cycle; '
                     '"start only": read-only):')
        lines += [p.help_line() for p in params]
    else:
        lines.append('parameters: declared by the node at start (no table to print)')
    return '\n'.join(lines) + '\n'

