"""The console-script entry point of every node executable: the stop handlers first
(`catheter_common.stop_signals`), then the node's module, then its ``main``.

A node module imports rclpy, numpy and its models (0.3 s on a quiet machine, seconds under
load) before its ``main`` could install anything; this module imports nothing heavy, so the
handlers are in place from the first moments of the process. The attribute names the node
module with ``__`` for the dot: ``catheter_common.node_entry:sim_slave__sim_slave_node`` runs
``sim_slave.sim_slave_node.main`` (see each package's setup.py).

It also registers faulthandler on SIGUSR1: ``kill -USR1 <pid>`` prints the Python stack of
every thread of a running node to its stderr (how tests/nodes/test_processes.py reports a node
that did not stop)."""
from __future__ import annotations

import faulthandler
import importlib
import signal
from typing import Callable

from catheter_common import stop_signals


def module_of(name: str) -> str:
    """'sim_slave__sim_slave_node' -> 'sim_slave.sim_slave_node' (ValueError if malformed)."""
    pkg, sep, mod = name.partition('__')
    if not sep or not pkg.isidentifier() or not mod.isidentifier() or '__' in mod:
        raise ValueError(f'a node entry is <package>__<module>, got {name!r}')
    return f'{pkg}.{mod}'


def entry(module: str) -> Callable[..., int]:
    """The ``main(args=None)`` of node module `module`, with the stop handlers installed before
    the module is imported."""
    def main(args=None) -> int:
        stop_signals.install()
        faulthandler.register(signal.SIGUSR1, all_threads=True)
        return importlib.import_module(module).main(args)
    main.__doc__ = f'Run {module} as a node executable (stop handlers first).'
    return main


def __getattr__(name: str) -> Callable[..., int]:
    if name.startswith('__'):
        raise AttributeError(name)
    try:
        return entry(module_of(name))
    except ValueError as exc:
        raise AttributeError(str(exc)) from None
