"""The stop handlers of a node executable: SIGINT and SIGTERM set a flag instead of raising.

Pure Python (no rclpy, no numpy): the executables' entry point (`catheter_common.node_entry`)
installs them before it imports the node's module, so a signal that arrives while the
process is still importing (0.3 s on a quiet machine, over 5 s with ten nodes starting on two
loaded cores) is noted and stops the node once it is built, instead of:

- raising KeyboardInterrupt in the middle of an import (a traceback, exit status -2), or
  ending the process by SIGTERM's default action (-15);
- being discarded: a process started with SIGINT ignored (a background job of a shell without
  job control, ``nohup``, some supervisors) has SIGINT ignored until a handler is installed,
  so a Ctrl-C sent during the imports was lost and the node then ran until killed (issue 15,
  found with `tests/bench/stress_node_signals.py`).

`catheter_common.ros_node.run_node` takes over the installed flag (or installs it when the
node was started another way) and restores the previous handlers when the node has stopped.
"""
from __future__ import annotations

import signal
from typing import Dict, Optional

#: the signals that stop a node cleanly, and how the logs name them
STOP_SIGNALS = {signal.SIGINT: 'SIGINT (Ctrl-C)', signal.SIGTERM: 'SIGTERM'}


class StopFlag:
    """Set by the signal handlers (the first signal wins); the spin loop checks it."""

    def __init__(self):
        self.signum: Optional[int] = None

    def __call__(self, signum, _frame) -> None:
        if self.signum is None:
            self.signum = signum

    @property
    def name(self) -> str:
        """How the logs name the signal that set the flag ('' before one did)."""
        if self.signum is None:
            return ''
        return STOP_SIGNALS.get(self.signum, f'signal {self.signum}')

    def __repr__(self) -> str:
        return f'StopFlag(signum={self.signum})'


_flag: Optional[StopFlag] = None
_previous: Dict[int, object] = {}


def install() -> StopFlag:
    """Install the stop handlers for SIGINT and SIGTERM (main thread only) and return their
    flag. Idempotent: while installed, the same flag is returned (with a signal that arrived
    in between already noted)."""
    global _flag
    if _flag is not None and all(signal.getsignal(s) is _flag for s in STOP_SIGNALS):
        return _flag
    flag = StopFlag()
    previous = {s: signal.signal(s, flag) for s in STOP_SIGNALS}
    if _flag is None:
        _previous.clear()
        _previous.update(previous)
    _flag = flag
    return flag


def restore() -> None:
    """Put back the handlers that were installed before `install` (nothing if not installed)."""
    global _flag
    if _flag is None:
        return
    for s, h in _previous.items():
        signal.signal(s, h if h is not None else signal.SIG_DFL)
    _previous.clear()
    _flag = None


def installed() -> Optional[StopFlag]:
    """The flag of the installed handlers, None when they are not installed."""
    return _flag
