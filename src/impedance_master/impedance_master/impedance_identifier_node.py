"""ROS 2 node `impedance_identifier_node` (slave side): identifies the catheter-vessel
environment from the slave's joint states and publishes the model.

Subscribes  /slave/joint_state  sensor_msgs/JointState: position[0] insertion m, velocity[0]
                                m/s (optional: differentiated if absent), effort[0] measured
                                insertion force N. QOS_FAST.
Publishes   /slave/impedance    sensor_msgs/JointState used as stamped named float64 values:
                                name = Impedance.to_fields() names (first 'm', 'c', 'k',
                                'offset', 'valid'), position = values; header.frame_id
                                catheter_base. At `publish_rate` Hz, QOS_FAST, while subscribed.
            /diagnostics        samples, bad messages, published models, held estimates
                                (status at_rest / ill_conditioned), solves, identifier status.
Parameters: identifier (default | thesis), window s, rate Hz (sample rate of the joint
states), publish_rate Hz (50-1000), state_file (default identifier only: a JSON file of the
learned information, loaded at start if it exists and written at shutdown, so the model
keeps learning across sessions on the same phantom; '' = none). Every sample is learned from, subscribed or not (the
default model learns from the whole history); publishing happens only while subscribed.
Thin: the identification is impedance_master.identification.
"""
from __future__ import annotations

import math
import os

from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common.ros_node import Diagnostics, declare, run_node
from catheter_common.topics import FRAME_CATHETER_BASE, SLAVE_IMPEDANCE, SLAVE_JOINT_STATE
from catheter_common.qos import QOS_FAST
from impedance_master.identification import SlidingWindowIdentifier, make_identifier


class ImpedanceIdentifierNode(Node):
    """Slave-side identification node (see module doc)."""

    def __init__(self, **kwargs):
        super().__init__('impedance_identifier_node', **kwargs)
        self.kind = declare(self, 'identifier', 'default',
                            'default: the history model (make_identifier); thesis: the '
                            'sliding-window linear fit of Eq. 34', choices=('default', 'thesis'))
        window = declare(self, 'window', 1.0, 'identification window, s', 0.05, 10.0)
        rate = declare(self, 'rate', 1000.0, 'sample rate of /slave/joint_state, Hz',
                       10.0, 10000.0)
        self.publish_rate = declare(self, 'publish_rate', 1000.0,
                                    'rate of /slave/impedance, Hz', 50.0, 1000.0)
        self.state_file = declare(self, 'state_file', '',
                                  'JSON file of the default identifier\'s learned state: '
                                  'loaded at start if present, written at shutdown ("": none)')
        self.model = None
        if self.kind == 'thesis':
            self.ident = SlidingWindowIdentifier(window=window, rate=rate)
        else:
            self.ident = make_identifier(window=window, rate=rate)
            if self.state_file and os.path.exists(self.state_file):
                try:
                    self.model = self.ident.load_state(self.state_file)
                    self.get_logger().info(f'continuing from the learned state in '
                                           f'{self.state_file} ({self.ident.n_moving} samples '
                                           'of motion)')
                except (OSError, ValueError) as exc:
                    self.get_logger().warning(f'ignoring state file {self.state_file}: {exc}')
        self._published_model = None
        self.diag = Diagnostics(self)
        self.pub = self.create_publisher(JointState, SLAVE_IMPEDANCE, QOS_FAST)
        self.sub = self.create_subscription(JointState, SLAVE_JOINT_STATE, self._on_state,
                                            QOS_FAST)
        self.timer = self.create_timer(1.0 / self.publish_rate, self._publish)
        self._diag_timer = self.create_timer(1.0, self._to_diag)
        self.get_logger().info(
            f'identifying the environment ({self.kind} identifier, window {window:g} s at '
            f'{rate:g} Hz) from {SLAVE_JOINT_STATE}; publishing {SLAVE_IMPEDANCE} at '
            f'{self.publish_rate:g} Hz')

    def _bad(self, why: str) -> None:
        self.diag.count('bad_messages')
        self.diag.error(why)
        self.get_logger().warning(f'bad joint state: {why}', throttle_duration_sec=2.0)

    def _on_state(self, msg: JointState) -> None:
        if len(msg.position) < 1 or len(msg.effort) < 1:
            self._bad('position and effort must hold [insertion m, ...] and [force N, ...]')
            return
        x, f = msg.position[0], msg.effort[0]
        xd = msg.velocity[0] if len(msg.velocity) >= 1 else None
        if not (math.isfinite(x) and math.isfinite(f) and (xd is None or math.isfinite(xd))):
            self._bad(f'non-finite values x={x!r} xd={xd!r} f={f!r}')
            return
        try:
            out = self.ident.update(x, xd, None, f)
        except ValueError as exc:  # pragma: no cover - inputs are checked above
            self._bad(str(exc))
            return
        self.diag.count('samples')
        if out is not None:
            if out is not self.model:
                self.diag.count('model_updates')
            self.model = out
            if self.ident.status != 'ok':
                self.diag.count('held_' + self.ident.status)

    def _publish(self) -> None:
        if self.model is None or self.pub.get_subscription_count() == 0:
            return
        fields = self.model.to_fields()
        msg = JointState()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = FRAME_CATHETER_BASE
        msg.name = list(fields)
        msg.position = list(fields.values())
        self.pub.publish(msg)
        self.diag.count('published')

    def close(self) -> None:
        """Write the learned state (default identifier, state_file set)."""
        if self.state_file and self.kind == 'default':
            try:
                self.ident.save_state(self.state_file)
                self.get_logger().info(f'learned state written to {self.state_file}')
            except OSError as exc:
                self.get_logger().error(f'could not write {self.state_file}: {exc}')

    def _to_diag(self) -> None:
        self.diag.set('identifier', self.kind)
        self.diag.set('status', self.ident.status)
        self.diag.set('held_total', self.ident.n_held)
        if self.model is not None:
            self.diag.set('model_valid', str(self.model.valid))
            self.diag.set('model_kind', 'table' if self.model.kind else 'linear')


NODE_CLASS = ImpedanceIdentifierNode


def main(args=None):
    return run_node(NODE_CLASS, args)


if __name__ == '__main__':
    raise SystemExit(main())
