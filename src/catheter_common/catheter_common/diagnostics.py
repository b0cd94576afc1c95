"""`Diagnostics`: what a node counts, measures and worries about, on /diagnostics.

Counters (`count`), values (`set`) and **conditions with levels**. A condition is named and
has a level (OK, WARN, ERROR) and a message:

- `condition(name, level, message)` holds while the node says so (a link outage, a model
  held, no model yet) and clears when the node sets it back to OK;
- `event(name, level, message, hold)` is raised by something that happened (a bad message,
  an estimate out of its envelope, a clamp) and clears by itself `hold` seconds of node
  clock after the last occurrence;
- `bad_input(what, why)` is the one way a node refuses a message: counts ``bad_messages`` and
  ``bad_<what>``, logs at most once per `log_period` s of wall time per kind (with the number
  held back) and raises a WARN event.

The published level is the highest active condition's; the message lists the active ones,
worst first; every active condition is also a key ``condition.<name>``. Functions given to
`add_updater` run right before each status is built (a node's conditions and values that
are polled rather than raised: link outage, model age, ...).
"""
from __future__ import annotations

import time
from typing import Callable, Dict, List, Optional, Tuple

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from catheter_common.qos import QOS_DEFAULT
from catheter_common.topics import DIAGNOSTICS

OK, WARN, ERROR = 0, 1, 2
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR'}
_LEVEL_BYTES = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN,
                ERROR: DiagnosticStatus.ERROR}


class Diagnostics:
    """Counters, values and leveled conditions of one node, published every `period` s."""

    def __init__(self, node, period: float = 1.0, hardware_id: str = 'sim',
                 log_period: float = 2.0):
        self._node = node
        self._name = node.get_fully_qualified_name()
        self._hw = hardware_id
        self._period = float(period)
        self._log_period = float(log_period)
        self._counts: Dict[str, int] = {}
        self._last_counts: Dict[str, int] = {}
        self._values: Dict[str, str] = {}
        #: name -> (level, message, node-clock time of the event in ns or None, hold ns)
        self._conds: Dict[str, Tuple[int, str, Optional[int], int]] = {}
        self._logged: Dict[str, list] = {}     # kind -> [wall time of the last log, held back]
        self._updaters: List[Callable[[], None]] = []
        self._pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS, QOS_DEFAULT)
        self._t_last = node.get_clock().now()
        self._timer = node.create_timer(period, self.publish)

    def add_updater(self, fn: Callable[[], None]) -> None:
        """Call `fn` before every status (to refresh polled conditions and values)."""
        self._updaters.append(fn)

    def refresh(self) -> None:
        for fn in self._updaters:
            fn()

    # ---------------------------------------------------------------- counters and values
    def count(self, key: str, n: int = 1) -> None:
        self._counts[key] = self._counts.get(key, 0) + n

    def get(self, key: str) -> int:
        return self._counts.get(key, 0)

    def set(self, key: str, value) -> None:
        self._values[key] = value if isinstance(value, str) else f'{value:.6g}' \
            if isinstance(value, float) else str(value)

    def value(self, key: str) -> Optional[str]:
        return self._values.get(key)

    # ---------------------------------------------------------------- conditions
    def condition(self, name: str, level: int, message: str = '') -> None:
        """Set condition `name` (held until changed); level OK clears it."""
        if level == OK:
            self._conds.pop(name, None)
        else:
            self._conds[name] = (int(level), message, None, 0)

    def event(self, name: str, level: int, message: str, hold: float = 2.0) -> None:
        """Raise condition `name` for `hold` s of node clock after now (refreshed by each call)."""
        now = self._node.get_clock().now().nanoseconds
        old = self._conds.get(name)
        if old is not None and old[2] is None and old[0] > level:
            return         # a held condition of a higher level stays as it is
        self._conds[name] = (int(level), message, now, int(hold * 1e9))

    def error(self, message: str, key: str = 'errors') -> None:
        """Count `key` and raise a WARN event for one period (the older API)."""
        self.count(key)
        self.event(key, WARN, message, hold=self._period)

    def bad_input(self, what: str, why: str, level: int = WARN, hold: float = 2.0) -> None:
        """A refused message: counted (bad_messages, bad_<what>), logged rate-limited,
        a WARN event for `hold` s."""
        self.count('bad_messages')
        self.count('bad_' + what)
        text = f'bad {what}: {why}'
        self.event('bad_' + what, level, text, hold=hold)
        self.log_limited('bad_' + what, text)

    def log_limited(self, kind: str, text: str, level: int = WARN) -> None:
        """Log `text` at most once per log_period s (wall time) per `kind`."""
        t = time.monotonic()
        slot = self._logged.get(kind)
        if slot is not None and t - slot[0] < self._log_period:
            slot[1] += 1
            return
        held = slot[1] if slot is not None else 0
        self._logged[kind] = [t, 0]
        log = self._node.get_logger()
        msg = text + (f' ({held} more since the last report)' if held else '')
        # two call sites: rclpy refuses two severities from one line of code
        if level >= ERROR:
            log.error(msg)
        else:
            log.warning(msg)

    def active(self) -> Dict[str, Tuple[int, str]]:
        """The conditions active now: name -> (level, message)."""
        now = self._node.get_clock().now().nanoseconds
        out = {}
        for name, (lvl, msg, t, hold) in list(self._conds.items()):
            if t is not None and not (0 <= now - t < hold):
                del self._conds[name]
                continue
            out[name] = (lvl, msg)
        return out

    def level(self) -> Tuple[int, str]:
        """(level, message) now (updaters run first): the worst active condition, 'ok'
        when none."""
        self.refresh()
        act = self.active()
        if not act:
            return OK, 'ok'
        items = sorted(act.items(), key=lambda kv: (-kv[1][0], kv[0]))
        return items[0][1][0], '; '.join(m or n for n, (_, m) in items)

    # ---------------------------------------------------------------- publishing
    def status(self) -> DiagnosticStatus:
        now = self._node.get_clock().now()
        dt = (now - self._t_last).nanoseconds * 1e-9
        self._t_last = now
        st = DiagnosticStatus()
        st.name = self._name
        st.hardware_id = self._hw
        lvl, message = self.level()      # runs the updaters
        st.level = _LEVEL_BYTES[lvl]
        st.message = message
        kv = []
        for k, v in sorted(self._counts.items()):
            kv.append(KeyValue(key=k, value=str(v)))
            if dt > 0:
                rate = (v - self._last_counts.get(k, 0)) / dt
                kv.append(KeyValue(key=k + '_rate_hz', value=f'{rate:.2f}'))
        self._last_counts = dict(self._counts)
        kv += [KeyValue(key=k, value=v) for k, v in sorted(self._values.items())]
        kv += [KeyValue(key='condition.' + n, value=f'{LEVEL_NAMES[lv]}: {m}')
               for n, (lv, m) in sorted(self.active().items())]
        st.values = kv
        return st

    def publish(self) -> None:
        st = self.status()
        msg = DiagnosticArray()
        msg.header.stamp = self._t_last.to_msg()
        msg.status = [st]
        self._pub.publish(msg)
