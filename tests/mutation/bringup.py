"""Mutants of catheter_bringup (the MCAP recorder and its run metadata, the recording QoS,
the run metrics) for tests/mutation/mutate.py: each breaks one property the package
promises; the recorder and metrics tests must kill every one.

    python tests/mutation/mutate.py bringup
"""
from mutate import Mutant

TESTS = ['tests/catheter_bringup/test_recorder.py', 'tests/catheter_bringup/test_analyze.py',
         'tests/catheter_bringup/test_recorder_metadata.py',
         'tests/catheter_bringup/test_metrics_skip.py']

P = 'src/catheter_bringup/catheter_bringup/'

MUTANTS = [
    # -- issue 14's six recorder metadata survivors
    Mutant('B01', P + 'recorder.py',
           '            self._seq[topic] = seq + 1',
           '            self._seq[topic] = seq',
           'issue 14 survivor: every message of a topic gets sequence number 0'),
    Mutant('B02', P + 'recorder.py',
           '            pub = log_time_ns if publish_time_ns is None else int(publish_time_ns)',
           '            pub = log_time_ns',
           'issue 14 survivor: the publish time given is dropped (log time recorded instead)'),
    Mutant('B03', P + 'recorder.py',
           '            if self.first_time_ns is None:\n                self.first_time_ns = '
           'log_time_ns',
           '            if True:\n                self.first_time_ns = log_time_ns',
           'issue 14 survivor: first_log_time_ns is the last message\'s time'),
    Mutant('B04', P + 'recorder.py',
           '                else max(self.last_time_ns, log_time_ns)',
           '                else log_time_ns',
           'issue 14 survivor: last_log_time_ns goes back with a late (out of order) message'),
    Mutant('B05', P + 'ros_recording.py',
           "        'durability': 'transient_local' if qos.durability == "
           "QoSDurabilityPolicy.TRANSIENT_LOCAL\n"
           "        else 'volatile',",
           "        'durability': 'volatile',",
           'issue 14 survivor: a latched (transient local) topic is recorded as volatile'),
    Mutant('B06', P + 'recorder.py',
           '        elif issubclass(exc_type, KeyboardInterrupt):',
           '        elif False:',
           'issue 14 survivor: Ctrl-C recorded as a failed run, not an interrupted one'),
    # -- the recorder's bytes and QoS
    Mutant('B07', P + 'recorder.py',
           '        data = bytes(data[:end])',
           '        data = bytes(data)',
           "rclpy's estimated-size padding is recorded (strict readers reject the message)"),
    Mutant('B08', P + 'ros_recording.py',
           '                      reliability=QoSReliabilityPolicy.BEST_EFFORT if best_effort\n'
           '                      else QoSReliabilityPolicy.RELIABLE,',
           '                      reliability=QoSReliabilityPolicy.RELIABLE,',
           'a reliable recording subscription to a best-effort publisher receives nothing'),
    Mutant('B09', P + 'recorder.py',
           "                'counts': json.dumps(self.counts, sort_keys=True),",
           "                'counts': json.dumps({}, sort_keys=True),",
           'the per-topic message counts are not recorded in the run metadata'),
    # -- run metrics
    Mutant('B10', P + 'metrics.py',
           '    fs = align(tm, t_slave, f_slave, shift=delay)',
           '    fs = align(tm, t_slave, f_slave, shift=0.0)',
           'force tracking compares with the slave force without the command delay'),
    Mutant('B11', P + 'metrics.py',
           '    out[(q < t_sig[0]) | (q > t_sig[-1])] = np.nan',
           '    pass',
           'align: samples outside the signal span are extrapolated instead of NaN'),
    Mutant('B12', P + 'metrics.py',
           "        out['rate_hz'] = float((t.size - 1) / span) if span > 0 else float('nan')",
           "        out['rate_hz'] = float(t.size / span) if span > 0 else float('nan')",
           'stream rate off by one message (N / span instead of (N - 1) / span)'),
    Mutant('B13', P + 'metrics.py',
           '    keep = rel >= skip',
           '    keep = rel >= 0.0',
           'force tracking: the start-up seconds (skip) are counted in the error'),
    # -- round 9 (issue 15): the recorder's fast Message path (fast_message_writer)
    Mutant('B14', P + 'recorder.py',
           '        stats.message_count += 1\n',
           '',
           'round 9: the file statistics count no message (the summary says 0 messages)'),
    Mutant('B15', P + 'recorder.py',
           '        elif log_time < cb.message_start_time:\n'
           '            cb.message_start_time = log_time',
           '        elif False:\n'
           '            cb.message_start_time = log_time',
           'round 9: a chunk\'s start time ignores an earlier message after its first'),
    Mutant('B16', P + 'recorder.py',
           '        index.records.append((log_time, buf.tell()))',
           '        index.records.append((log_time, 0))',
           'round 9: the message index points every message at the chunk\'s start'),
    Mutant('B17', P + 'recorder.py',
           'sequence, log_time, publish_time))',
           'sequence, log_time, log_time))',
           'round 9: the publish time given is dropped in the fast path'),
    Mutant('B18', P + 'recorder.py',
           '        finish()\n    return add',
           '    return add',
           'round 9: a chunk is never finished when full (one chunk per file)'),
    # -- issue 15, 2026-12-03: the link topics' receive queue (catheter_common.qos.QOS_LINK)
    Mutant('B19', 'src/catheter_common/catheter_common/qos.py',
           'QOS_LINK = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=100,',
           'QOS_LINK = QoSProfile(history=QoSHistoryPolicy.KEEP_LAST, depth=10,',
           'the link receiver keeps 10 samples: a stall over 10 ms loses what the link was sent',
           tests=('tests/catheter_bringup/test_link_qos.py',)),
    Mutant('B20', 'src/impedance_master/impedance_master/sim_haptic_node.py',
           'WrenchStamped, rel(T.SLAVE_FORCE), self._on_slave_force, QOS_LINK)',
           'WrenchStamped, rel(T.SLAVE_FORCE), self._on_slave_force, QOS_FAST)',
           'the master takes /slave/force with the shallow 1 kHz queue (lost in a stall)',
           tests=('tests/catheter_bringup/test_link_qos.py',)),
    Mutant('B21', 'src/sim_slave/sim_slave/sim_slave_node.py',
           '                                            self._on_command, QOS_LINK)',
           '                                            self._on_command, QOS_FAST)',
           'the slave takes /master/command with the shallow 1 kHz queue',
           tests=('tests/catheter_bringup/test_link_qos.py',)),
]
