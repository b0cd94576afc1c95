"""The simulated link's ROS parameters, declared the same way by every node that holds a side
of the link (sim_slave_node: commands master -> slave; sim_haptic_node: impedance and force
slave -> master)."""
from __future__ import annotations

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from catheter_common.ros_node import declare
from sim_slave.link import LinkConfig


def declare_link(node: Node, what: str) -> LinkConfig:
    """Declare link.delay, link.jitter, link.loss and link.outages on `node` (`what` names the
    traffic this side receives, for the descriptions) and return the LinkConfig they give."""
    delay = declare(node, 'link.delay', 0.2, f'one-way delay of {what}, s', 0.0, 10.0)
    jitter = declare(node, 'link.jitter', 0.0, f'extra delay U(0, jitter) per packet of {what}, s',
                     0.0, 5.0)
    loss = declare(node, 'link.loss', 0.0, f'probability that a packet of {what} is lost',
                   0.0, 1.0)
    outages = node.declare_parameter(
        'link.outages', [4.0, 1.0, 8.0, 1.0],
        ParameterDescriptor(description='link outages as a flat list start,length,... in s '
                            'after the first timer tick; [] or [0.0, 0.0] for none',
                            dynamic_typing=True)).value
    try:
        flat = [float(v) for v in (outages or [])]
    except (TypeError, ValueError):
        raise ValueError(f'link.outages must be a list of numbers, got {outages!r}') from None
    return LinkConfig.from_flat(delay, jitter, loss, flat)
