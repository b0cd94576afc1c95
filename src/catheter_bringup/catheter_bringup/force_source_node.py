"""`force_source_node`: the identification force from the image instead of the load cell.

Subscribes /slave/joint_state (insertion position, velocity; effort = load cell force) and
/catheter/tip_wrench (image-based tip force estimate, ~30 Hz) and publishes
/slave/joint_state_image: the same joint state with the insertion effort replaced by the latest
image-based estimate (held between frames). Scenarios with ``force_source: image`` remap the
identifier's input to it. Thin: message conversion only.

Parameters: ``component`` (magnitude | x | y: which part of the tip force is the insertion
force), ``sign`` (+1 or -1), ``max_age`` (s; older estimates are not used: the load cell value
passes through and is counted as a fallback).
"""
from __future__ import annotations

import math

from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common.ros_node import Diagnostics, declare, run_node
from catheter_common.topics import SLAVE_JOINT_STATE, TIP_WRENCH
from catheter_common.qos import QOS_FAST, QOS_SENSOR

SLAVE_JOINT_STATE_IMAGE = '/slave/joint_state_image'
COMPONENTS = ('magnitude', 'x', 'y')


class ForceSourceNode(Node):
    def __init__(self, **kwargs):
        super().__init__('force_source_node', **kwargs)
        self.component = declare(self, 'component', 'magnitude',
                                 'part of the tip force used as insertion force',
                                 choices=COMPONENTS)
        self.sign = declare(self, 'sign', 1.0, 'sign applied to the image force', -1.0, 1.0)
        self.max_age = declare(self, 'max_age', 0.2, 'oldest usable image estimate, s',
                               0.0, 10.0)
        if self.sign not in (-1.0, 1.0):
            raise ValueError(f'sign must be +1 or -1, got {self.sign}')
        self.force = None
        self.force_t = None
        self.diag = Diagnostics(self)
        self.pub = self.create_publisher(JointState, SLAVE_JOINT_STATE_IMAGE, QOS_FAST)
        self.create_subscription(WrenchStamped, TIP_WRENCH, self._on_wrench, QOS_SENSOR)
        self.create_subscription(JointState, SLAVE_JOINT_STATE, self._on_state, QOS_FAST)
        self.get_logger().info(f'{SLAVE_JOINT_STATE} + {TIP_WRENCH} ({self.component}) -> '
                               f'{SLAVE_JOINT_STATE_IMAGE}')

    def _on_wrench(self, msg: WrenchStamped):
        f = msg.wrench.force
        value = {'magnitude': math.hypot(f.x, f.y), 'x': f.x, 'y': f.y}[self.component]
        if not math.isfinite(value):
            self.diag.error(f'non-finite tip force {value}', 'bad_wrench')
            return
        self.force = self.sign * value
        self.force_t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.diag.count('estimates')

    def _on_state(self, msg: JointState):
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
        self.pub.publish(out)


NODE_CLASS = ForceSourceNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())
