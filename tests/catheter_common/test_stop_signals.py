"""catheter_common.stop_signals and node_entry: the stop handlers installed before a node's
module is imported, a signal noted (never raised, never lost) from then on, the previous
handlers restored at the end."""
import faulthandler
import os
import signal
import sys
import textwrap

import pytest

from catheter_common import node_entry, stop_signals


@pytest.fixture
def clean_handlers():
    old = {s: signal.getsignal(s) for s in stop_signals.STOP_SIGNALS}
    yield old
    stop_signals.restore()
    for s, h in old.items():
        signal.signal(s, h)


def test_install_notes_the_first_signal_and_restore_puts_back_the_handlers(clean_handlers):
    flag = stop_signals.install()
    assert stop_signals.installed() is flag and flag.signum is None and flag.name == ''
    assert stop_signals.install() is flag                 # idempotent: the same flag
    os.kill(os.getpid(), signal.SIGTERM)                  # noted, not the default action
    os.kill(os.getpid(), signal.SIGINT)                   # the first signal wins
    assert flag.signum == signal.SIGTERM and flag.name == 'SIGTERM'
    assert 'signum=15' in repr(flag)
    stop_signals.restore()
    assert stop_signals.installed() is None
    for s, h in clean_handlers.items():
        assert signal.getsignal(s) is h
    stop_signals.restore()                                # nothing installed: no-op


def test_install_over_a_replaced_handler_keeps_the_first_previous_handlers(clean_handlers):
    first = stop_signals.install()
    signal.signal(signal.SIGINT, signal.SIG_IGN)         # someone replaced ours
    second = stop_signals.install()
    assert second is not first and signal.getsignal(signal.SIGINT) is second
    stop_signals.restore()
    assert signal.getsignal(signal.SIGINT) is clean_handlers[signal.SIGINT]


@pytest.mark.parametrize('name, module', [
    ('sim_slave__sim_slave_node', 'sim_slave.sim_slave_node'),
    ('impedance_master__impedance_identifier_node',
     'impedance_master.impedance_identifier_node'),
])
def test_entry_names_map_to_node_modules(name, module):
    assert node_entry.module_of(name) == module
    assert callable(getattr(node_entry, name))


@pytest.mark.parametrize('bad', ['sim_slave', 'sim_slave__', '__x', 'a__b__c', 'a b__c',
                                 'sim_slave.x__y'])
def test_a_malformed_entry_name_is_refused(bad):
    with pytest.raises(ValueError, match='<package>__<module>'):
        node_entry.module_of(bad)
    with pytest.raises(AttributeError):
        getattr(node_entry, bad)


def test_the_entry_installs_the_handlers_before_importing_the_node_module(
        tmp_path, monkeypatch, clean_handlers):
    """The node module sees the stop handlers installed while it is imported (a signal then is
    noted), its main gets the call, and SIGUSR1 dumps the stacks (faulthandler)."""
    pkg = tmp_path / 'entry_probe_pkg'
    pkg.mkdir()
    (pkg / '__init__.py').write_text('')
    (pkg / 'slow_node.py').write_text(textwrap.dedent('''
        import os, signal
        from catheter_common import stop_signals
        AT_IMPORT = stop_signals.installed()
        os.kill(os.getpid(), signal.SIGINT)       # a Ctrl-C while the node still imports
        SEEN = AT_IMPORT.signum if AT_IMPORT is not None else 'no handler'

        def main(args=None):
            return (AT_IMPORT is not None, SEEN, args)
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    main = node_entry.entry_probe_pkg__slow_node
    installed, seen, args = main(['x'])
    assert installed and seen == signal.SIGINT and args == ['x']
    assert faulthandler.unregister(signal.SIGUSR1)      # kill -USR1: the stacks of a live node
    sys.modules.pop('entry_probe_pkg.slow_node', None)
    sys.modules.pop('entry_probe_pkg', None)
