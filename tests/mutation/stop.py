"""Mutants of issue 15's shutdown and link-loss work (round 8): the node executables' stop
handlers (catheter_common.stop_signals, node_entry, ros_node.run_node) and what DDS reports
lost on the split layout's link subscriptions (catheter_bringup bus, realtime, worker).

    python tests/mutation/mutate.py stop
"""
from mutate import Mutant

C = 'src/catheter_common/catheter_common/'
B = 'src/catheter_bringup/catheter_bringup/'
UNIT = ('tests/catheter_common/test_stop_signals.py', 'tests/catheter_common/test_run_node.py')
EARLY = ('tests/nodes/test_processes.py', '-k', 'still_starts')
TESTS = list(UNIT) + ['tests/catheter_bringup/test_realtime.py']

MUTANTS = [
    Mutant('S01', C + 'stop_signals.py',
           '        if self.signum is None:\n            self.signum = signum',
           '        self.signum = signum',
           'the last signal wins: a SIGINT after a SIGTERM renames the stop in the logs',
           tests=UNIT),
    Mutant('S02', C + 'stop_signals.py',
           "        signal.signal(s, h if h is not None else signal.SIG_DFL)",
           "        signal.getsignal(s)",
           'the handlers that were there before the node are not put back', tests=UNIT),
    Mutant('S03', C + 'stop_signals.py',
           '    if _flag is not None and all(signal.getsignal(s) is _flag for s in STOP_SIGNALS):',
           '    if False:',
           'install is not idempotent: run_node replaces the entry\'s flag and loses a signal '
           'that came while the node imported', tests=UNIT),
    Mutant('S04', C + 'node_entry.py',
           '        stop_signals.install()\n        faulthandler',
           '        faulthandler',
           'the entry point installs nothing: the handlers come with run_node, after the node '
           'module and rclpy were imported (the lost SIGINT)', tests=UNIT + EARLY),
    Mutant('S05', C + 'ros_node.py',
           '        if stop.signum is not None:\n            print(',
           '        if False:\n            print(',
           'a signal before run_node is ignored until the node is built: the node is started '
           'anyway', tests=UNIT),
    Mutant('S06', C + 'ros_node.py',
           '    finally:\n        stop_signals.restore()',
           '    finally:\n        pass',
           'run_node leaves its handlers installed after the node stopped', tests=UNIT),
    Mutant('S07', B + 'bus.py',
           "        self.dds_lost[topic] = sum(n for t, n in self._dds_lost_by_sub.values() "
           "if t == topic)",
           "        self.dds_lost[topic] = total",
           'a topic with two subscriptions reports the last one\'s losses only'),
    Mutant('S08', B + 'realtime.py',
           '    return {k: int(n) - int(before.get(k, 0)) for k, n in now.items() if k in keys}',
           '    return {k: int(n) for k, n in now.items() if k in keys}',
           'what DDS reported lost before the loop started is charged to the loop'),
    Mutant('S09', B + 'worker.py',
           '                                             dds_reported=reported.get((t, proc)))',
           '                                             dds_reported=None)',
           'the link report drops what DDS reported lost',
           tests=('tests/catheter_bringup/test_layout_split.py', '-k', 'link_topics_flow')),
    Mutant('S10', C + 'ros_node.py',
           '        watchdog = TeardownWatchdog(code)',
           '        watchdog = TeardownWatchdog(code, timeout=60.0)',
           'no teardown watchdog in practice: a destroy_node that blocks keeps the process '
           'running until it is killed (the hang of a fresh clone\'s full run)', tests=UNIT),
    Mutant('S11', C + 'ros_node.py',
           '            _hard_exit(self.code)',
           '            _hard_exit(1)',
           'a stuck teardown exits 1 although the node stopped as asked', tests=UNIT),
    Mutant('S12', C + 'ros_node.py',
           '        self._timer.cancel()\n',
           '        pass\n',
           'the watchdog is not cancelled: a node that tore down in time is still killed',
           tests=UNIT),
    Mutant('S13', C + 'ros_node.py',
           '            sev.value = int(code) & 0xFF',
           '            sev.value = 1',
           'the GIL-free backstop exits 1 whatever the node\'s code (the round-8 backstop)',
           tests=UNIT),
    Mutant('S14', C + 'ros_node.py',
           '        self._exit.cancel()\n',
           '        pass\n',
           'the GIL-free backstop is not cancelled: a node whose teardown finished is ended '
           'later anyway', tests=UNIT),
    Mutant('S15', C + 'ros_node.py',
           '            self._libc.timer_delete(self._timer)',
           '            pass',
           'cancel() leaves the POSIX timer running', tests=UNIT),
]
