"""`recorder_node`: records every topic of the graph (or a chosen list) into one MCAP file.

Parameters: ``path`` (output .mcap; default bags/recording_<date>.mcap under the workspace),
``topics`` (record only these; empty = all), ``exclude`` (never these), ``discovery_period`` (s),
``scenario`` (the scenario being run, a name or YAML path: the launch file passes it; its YAML,
with ``mode: realtime``, goes into the recording's run metadata at the start and at the end, so
`analyze` knows the link delay and outages). On shutdown (Ctrl-C / SIGTERM) the file is
closed with its summary and a ``catheter_run`` record.
"""
from __future__ import annotations

import datetime
import os
import pathlib

from rclpy.node import Node

from catheter_bringup.recorder import McapRecorder
from catheter_bringup.ros_recording import RecordingSink
from catheter_common.ros_node import Diagnostics, declare, node_main


def default_bag_dir() -> pathlib.Path:
    root = os.environ.get('CATHETER_WS_ROOT')
    if root:
        return pathlib.Path(root) / 'bags'
    return pathlib.Path.cwd() / 'bags'


class RecorderNode(Node):
    def __init__(self, **kwargs):
        super().__init__('recorder_node', **kwargs)
        path = declare(self, 'path', '', 'output MCAP file (empty: bags/recording_<date>.mcap)')
        topics = declare(self, 'topics', [''], 'record only these topics (empty: every topic)')
        exclude = declare(self, 'exclude', ['/rosout', '/parameter_events'],
                          'topics never recorded')
        period = declare(self, 'discovery_period', 0.5,
                         'period of the graph scan for new topics, s', 0.05, 10.0)
        scenario = declare(self, 'scenario', '',
                           'scenario being run (name or YAML path; empty: none), recorded '
                           'as the run metadata', read_only=True)
        self.run_info = {}
        if scenario:
            from catheter_bringup.scenario import load_scenario, run_start_info
            sc = load_scenario(scenario)
            sc['mode'] = 'realtime'          # launched nodes run on the system clock
            self.run_info = run_start_info(sc, [])
        if not path:
            stamp = datetime.datetime.now().strftime('%Y%m%d_%H%M%S')  # file name only
            path = str(default_bag_dir() / f'recording_{stamp}.mcap')
        self.recorder = McapRecorder(path)
        if self.run_info:
            self.recorder.start(self.run_info)
        only = [t for t in topics if t]
        self.sink = RecordingSink(self, self.recorder, exclude=exclude, only=only or None)
        self.diag = Diagnostics(self)
        self._scan_timer = self.create_timer(period, self._scan)
        self._scan()
        self.get_logger().info(f'recording to {path}')

    def _scan(self):
        for t in self.sink.discover():
            self.get_logger().info(f'recording {t}')
        self.diag.set('messages', self.recorder.total)
        self.diag.set('topics', len(self.sink.subs))
        self.diag.set('write_errors', self.sink.errors)

    def close(self):
        if not self.recorder.closed:
            extra = {k: v for k, v in self.run_info.items() if k != 'nodes'}
            self.recorder.close('complete', 'recorder_node shut down', extra=extra)
            self.get_logger().info(
                f'closed {self.recorder.path}: {self.recorder.total} messages')


NODE_CLASS = RecorderNode


main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())
