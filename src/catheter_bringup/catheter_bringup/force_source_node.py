"""`force_source_node`: the identification force from the image instead of the load cell.

Subscribes slave/joint_state (insertion position, velocity; effort = load cell force) and
catheter/tip_wrench (image-based tip force estimate, ~30 Hz) and publishes
slave/joint_state_image: the same joint state with the insertion effort replaced by the latest
image-based estimate (held between frames). Scenarios with ``force_source: image`` remap the
identifier's input to it. Topic names are relative (the node's namespace applies). Thin:
message conversion only.

Parameters (all apply at run time): ``component`` (magnitude | x | y: which part of the tip
force is the insertion force), ``sign`` (+1 or -1), ``max_age`` (s; older estimates are not
used: the load cell value passes through, counted as a fallback and reported as WARN).
"""
from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common import topics as T
from catheter_common.checks import all_finite, finite
from catheter_common.diagnostics import WARN, Diagnostics
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST, QOS_SENSOR
from catheter_common.ros_node import node_main

COMPONENTS = ('magnitude', 'x', 'y')

PARAMS = table(
    Param('component', 'magnitude', 'part of the tip force used as insertion force',
          choices=COMPONENTS, dynamic=True),
    Param('sign', 1.0, 'sign applied to the image force', choices=(-1.0, 1.0), dynamic=True),
    Param('max_age', 0.2, 'oldest usable image estimate, s', 0.0, 10.0, dynamic=True),
)


class ForceSourceNode(Node):
    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('force_source_node', **kwargs)
        self.params = NodeParams(self, PARAMS, apply=self._apply_params)
        self._apply_params({}, self.params.values)
        self.force = None
        self.force_t = None
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        self.pub = self.create_publisher(JointState, T.relative(T.SLAVE_JOINT_STATE_IMAGE),
                                         QOS_FAST)
        self.sub_wrench = self.create_subscription(WrenchStamped, T.relative(T.TIP_WRENCH),
                                                   self._on_wrench, QOS_SENSOR)
        self.sub_state = self.create_subscription(JointState, T.relative(T.SLAVE_JOINT_STATE),
                                                  self._on_state, QOS_FAST)
        self.get_logger().info(f'{self.sub_state.topic_name} + {self.sub_wrench.topic_name} '
                               f'({self.component}) -> {self.pub.topic_name}')

    def _apply_params(self, changes, values) -> None:
        self.component = values['component']
        self.sign = values['sign']
        self.max_age = values['max_age']

    def _on_wrench(self, msg: WrenchStamped):
        f = msg.wrench.force
        value = {'magnitude': math.hypot(f.x, f.y), 'x': f.x, 'y': f.y}[self.component]
        try:
            value = finite(f'tip force ({self.component})', value)
        except ValueError as exc:
            self.diag.bad_input('wrench', str(exc))
            return
        self.force = self.sign * value
        self.force_t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.diag.count('estimates')

    def _on_state(self, msg: JointState):
        try:
            for field in ('position', 'velocity', 'effort'):
                all_finite(field, getattr(msg, field))
        except ValueError as exc:
            self.diag.bad_input('joint_state', str(exc))
            return
        out = JointState()
        out.header = msg.header
        out.name = list(msg.name)
        out.position = list(msg.position)
        out.velocity = list(msg.velocity)
        out.effort = list(msg.effort)
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if self.force is not None and out.effort and t - self.force_t <= self.max_age:
            out.effort[0] = self.force
            self.diag.count('replaced')
        else:
            self.diag.count('load_cell_fallback')
            self.diag.event('fallback', WARN, 'no recent image force estimate: the load cell '
                            'force passes through', hold=0.5)
        self.pub.publish(out)


NODE_CLASS = ForceSourceNode
main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())
