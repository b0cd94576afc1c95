"""Small nodes of the tests (the infrastructure is tested without the project's real nodes).
They follow the node conventions: **kwargs to Node, node name == class's executable name."""
import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Image, JointState

from catheter_common.qos import QOS_DEFAULT, QOS_FAST, QOS_SENSOR


class TalkerNode(Node):
    """1 kHz WrenchStamped on /test/force: a seeded random walk (deterministic for a seed)."""

    def __init__(self, **kwargs):
        super().__init__('talker', **kwargs)
        seed = self.declare_parameter('seed', 0).value
        rate = self.declare_parameter('rate', 1000.0).value
        self.rng = np.random.default_rng(seed)
        self.value = 0.0
        self.pub = self.create_publisher(WrenchStamped, '/test/force', QOS_FAST)
        self.timer = self.create_timer(1.0 / rate, self.tick)
        self.closed = False

    def tick(self):
        self.value += float(self.rng.normal(0, 0.01))
        m = WrenchStamped()
        m.header.stamp = self.get_clock().now().to_msg()
        m.header.frame_id = 'catheter_base'
        m.wrench.force.x = self.value
        self.pub.publish(m)

    def close(self):
        self.closed = True


class RelayNode(Node):
    """Subscribes /test/force, republishes the value as JointState on /test/relayed."""

    def __init__(self, **kwargs):
        super().__init__('relay', **kwargs)
        self.pub = self.create_publisher(JointState, '/test/relayed', QOS_FAST)
        self.sub = self.create_subscription(WrenchStamped, '/test/force', self.cb, QOS_FAST)

    def cb(self, msg):
        out = JointState()
        out.header = msg.header
        out.name = ['x']
        out.position = [msg.wrench.force.x]
        self.pub.publish(out)


class InfoRelayNode(Node):
    """Like RelayNode, with a callback that takes the message info too (callback(msg, info))."""

    def __init__(self, **kwargs):
        super().__init__('info_relay', **kwargs)
        self.pub = self.create_publisher(JointState, '/test/info_relayed', QOS_FAST)
        self.sub = self.create_subscription(WrenchStamped, '/test/force', self.cb, QOS_FAST)

    def cb(self, msg, info):
        out = JointState()
        out.header = msg.header
        out.name = ['x']
        out.position = [msg.wrench.force.x]
        self.pub.publish(out)


class FakeCameraNode(Node):
    """30 Hz mono8 64x48 frames on /test/image."""

    def __init__(self, **kwargs):
        super().__init__('fake_camera', **kwargs)
        self.pub = self.create_publisher(Image, '/test/image', QOS_SENSOR)
        self.timer = self.create_timer(1.0 / 30.0, self.tick)
        self.k = 0

    def tick(self):
        img = Image()
        img.header.stamp = self.get_clock().now().to_msg()
        img.header.frame_id = 'camera_optical_frame'
        img.height, img.width, img.encoding, img.step = 48, 64, 'mono8', 64
        img.data = bytes([(self.k + i) % 256 for i in range(48 * 64)])
        self.k += 1
        self.pub.publish(img)


class UnusedNode(Node):
    """Produces a topic no scene consumes: the runner must not start it."""

    def __init__(self, **kwargs):
        super().__init__('unused', **kwargs)
        raise RuntimeError('UnusedNode must not be started')


class FailingNode(Node):
    """Raises in its timer once the clock passes fail_at (s)."""

    def __init__(self, **kwargs):
        super().__init__('failing', **kwargs)
        self.fail_at = self.declare_parameter('fail_at', 0.5).value
        self.pub = self.create_publisher(WrenchStamped, '/test/failing', QOS_DEFAULT)
        self.timer = self.create_timer(0.01, self.tick)

    def tick(self):
        t = self.get_clock().now().nanoseconds * 1e-9
        if t >= self.fail_at:
            raise RuntimeError(f'simulated node failure at t={t:.3f} s')
        m = WrenchStamped()
        m.header.stamp = self.get_clock().now().to_msg()
        self.pub.publish(m)


TalkerNode.NODE_CLASS = TalkerNode


class BadCloseNode(Node):
    """Publishes on /test/bad_close every 10 ms; its close() raises (a node whose shutdown
    fails must not cost the run its recording or the other nodes their close)."""

    def __init__(self, **kwargs):
        super().__init__('bad_close', **kwargs)
        self.pub = self.create_publisher(WrenchStamped, '/test/bad_close', QOS_DEFAULT)
        self.timer = self.create_timer(0.01, lambda: self.pub.publish(WrenchStamped()))

    def close(self):
        raise OSError('disk full while saving')
