"""A node module of the lockstep vision-process tests (importable by the vision process):
`SamplerNode` keeps the newest value of each input and publishes them every `period` s;
with ``echo`` it republishes each message of its first input when it takes it (a cascade);
with ``fail_at`` its timer raises once the clock passes it; ``tag`` goes into torque.y; with
``only_subscribed`` it publishes only while its topic has a subscriber."""
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node

from catheter_common.qos import QOS_FAST


class SamplerNode(Node):
    def __init__(self, **kwargs):
        super().__init__('sampler', **kwargs)
        ins = self.declare_parameter('inputs', ['/test/force']).value
        out = self.declare_parameter('output', '/test/sampled').value
        period = self.declare_parameter('period', 0.001).value
        self.fail_at = self.declare_parameter('fail_at', -1.0).value
        echo = self.declare_parameter('echo', '').value
        self.tag = self.declare_parameter('tag', 0.0).value
        self.only_subscribed = self.declare_parameter('only_subscribed', False).value
        self.values = [0.0] * len(ins)
        self.taken = 0
        self.pub = self.create_publisher(WrenchStamped, out, QOS_FAST)
        self.echo = self.create_publisher(WrenchStamped, echo, QOS_FAST) if echo else None
        self.subs = [self.create_subscription(WrenchStamped, t, self._taker(k), QOS_FAST)
                     for k, t in enumerate(ins)]
        self.timer = self.create_timer(period, self.tick)

    def _taker(self, k):
        def take(msg):
            self.values[k] = msg.wrench.force.x
            self.taken += 1
            if k == 0 and self.echo is not None:
                self.echo.publish(msg)
        return take

    def tick(self):
        now = self.get_clock().now()
        if 0 <= self.fail_at <= now.nanoseconds * 1e-9:
            raise RuntimeError(f'sampler failure at t={now.nanoseconds * 1e-9:.3f} s')
        if self.only_subscribed and self.pub.get_subscription_count() == 0:
            return
        m = WrenchStamped()
        m.header.stamp = now.to_msg()
        m.wrench.force.x = self.values[0]
        m.wrench.force.y = self.values[-1]
        m.wrench.torque.x = float(self.taken)
        m.wrench.torque.y = self.tag
        self.pub.publish(m)


NODE_CLASS = SamplerNode
