"""ROS 2 node `impedance_identifier_node` (slave side): identifies the catheter-vessel
environment from the slave's joint states and publishes the model.

Subscribes  slave/joint_state  sensor_msgs/JointState: position[0] insertion m, velocity[0]
                               m/s (the thesis identifier differentiates x when it is absent;
                               the default one refuses such a message), effort[0] measured
                               insertion force N. QOS_FAST.
Publishes   slave/impedance    catheter_interfaces/ImpedanceModel: the model (kind, m, c, k,
                               offset, valid, grid and tables, anchor, the identifier's
                               status; catheter_common.messages.impedance_msg of
                               Impedance.to_fields()); header.frame_id catheter_base. At
                               `publish_rate` Hz, QOS_FAST, while subscribed.
            /diagnostics       samples, bad messages, published models, held estimates
                               (status at_rest / ill_conditioned), solves, identifier status;
                               WARN while no model exists or the model is held, ERROR when it
                               has been ill-conditioned for `stuck_after` s, WARN after bad
                               messages.
Parameters: identifier (default | thesis), window s, rate Hz (sample rate of the joint
states), publish_rate Hz (50-1000, applies at run time), state_file (default identifier
only: a JSON file of the learned information, loaded at start if it exists and written at
shutdown, so the model keeps learning across sessions on the same phantom; '' = none; the
core's StateFile: a file it rejects is never overwritten, the new state is written beside it,
<stem>.<n>.json, and the rejection is a WARN). Every sample is learned from, subscribed or
not (the default model learns from the whole history); publishing happens only while
subscribed. Topic names are relative (the node's namespace applies). Thin: the
identification is impedance_master.identification.
"""
from __future__ import annotations

import math

from catheter_interfaces.msg import ImpedanceModel
from rclpy.node import Node
from sensor_msgs.msg import JointState

from catheter_common import topics as T
from catheter_common.checks import first
from catheter_common.diagnostics import ERROR, WARN, Diagnostics
from catheter_common.messages import impedance_msg
from catheter_common.outgoing import set_stamp
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST
from catheter_common.ros_node import clock_ns, node_main
from impedance_master.identification import SlidingWindowIdentifier, make_identifier
from impedance_master.state_file import StateFile

PARAMS = table(
    Param('identifier', 'default', 'default: the history model (make_identifier); thesis: the '
          'sliding-window linear fit of Eq. 34', choices=('default', 'thesis')),
    Param('window', 1.0, 'identification window, s', 0.05, 10.0),
    Param('rate', 1000.0, 'sample rate of slave/joint_state, Hz', 10.0, 10000.0),
    Param('publish_rate', 1000.0, 'rate of slave/impedance, Hz', 50.0, 1000.0, dynamic=True),
    Param('state_file', '', 'JSON file of the default identifier\'s learned state: loaded at '
          'start if present, written at shutdown ("": none)'),
    Param('stuck_after', 10.0, 'an identifier ill-conditioned this long is an ERROR, s',
          0.1, 3600.0, dynamic=True),
)


class ImpedanceIdentifierNode(Node):
    """Slave-side identification node (see module doc)."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('impedance_identifier_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self.kind = p['identifier']
        window, rate = p['window'], p['rate']
        self.publish_rate = p['publish_rate']
        self.state_file = p['state_file']
        self.model = None
        #: the learned state on disk (default identifier, state_file set): loaded now, saved
        #: at close(); a file it rejects is kept and the new state goes beside it
        self.sf = None
        if self.kind == 'thesis':
            self.ident = SlidingWindowIdentifier(window=window, rate=rate)
        else:
            self.ident = make_identifier(window=window, rate=rate)
            if self.state_file:
                self.sf = StateFile(self.state_file)
                self.model = self.sf.load(self.ident)
                self._sf_message = self.sf.message
                if self.sf.rejected:
                    self.get_logger().warning(self.sf.message)
                else:
                    self.get_logger().info(self.sf.message)
        self._published_model = None
        self._ill_since = None       # node-clock ns since when the status is ill_conditioned
        self.diag = Diagnostics(self)
        self.diag.count('bad_messages', 0)
        self._msg = None             # the message of _published_model (re-stamped when held)
        self._clock = self.get_clock()   # the same object for the node's life
        self._clock_ns = clock_ns(self._clock)
        self.pub = self.create_publisher(ImpedanceModel, T.relative(T.SLAVE_IMPEDANCE),
                                         QOS_FAST)
        self.sub = self.create_subscription(JointState, T.relative(T.SLAVE_JOINT_STATE),
                                            self._on_state, QOS_FAST)
        self.timer = self.create_timer(1.0 / self.publish_rate, self._publish)
        self.diag.add_updater(self._to_diag)
        self.get_logger().info(
            f'identifying the environment ({self.kind} identifier, window {window:g} s at '
            f'{rate:g} Hz) from {self.sub.topic_name}; publishing {self.pub.topic_name} at '
            f'{self.publish_rate:g} Hz')

    def _apply_params(self, changes, values) -> None:
        if 'publish_rate' in changes:
            self.publish_rate = values['publish_rate']
            self.timer.timer_period_ns = int(round(1e9 / self.publish_rate))
            self.timer.reset()          # the new period counts from now

    def _on_state(self, msg: JointState) -> None:
        try:
            x = first('position', msg.position)
            f = first('effort', msg.effort)
            xd = first('velocity', msg.velocity) if len(msg.velocity) else None
            if xd is None and self.kind != 'thesis':
                raise ValueError('velocity is empty (the default identifier needs it)')
        except ValueError as exc:
            self.diag.bad_input('joint_state', str(exc))
            return
        try:
            out = self.ident.update(x, xd, None, f)
        except ValueError as exc:           # the identifier failed on a finite sample
            self.diag.count('update_errors')
            self.diag.event('update_error', ERROR, f'identification failed: {exc!r}')
            self.diag.log_limited('update_error', f'identification failed on x={x!r} xd={xd!r} '
                                  f'f={f!r}: {exc!r}', ERROR)
            return
        self.diag.count('samples')
        if out is not None:
            if out is not self.model:
                self.diag.count('model_updates')
            self.model = out
            if self.ident.status not in ('ok', 'filling'):     # filling: anchor-only models
                self.diag.count('held_' + self.ident.status)

    def _publish(self) -> None:
        if self.model is None or self.pub.get_subscription_count() == 0:
            return
        ns = self._clock_ns()
        if self.model is not self._published_model or self._msg is None:
            # a new model: converted once (a held model is re-sent re-stamped in place:
            # serialised at publish, catheter_common.outgoing); a table model with an
            # anchor after another is written into the same message
            if not fill_table_msg(self._msg, self.model):
                self._msg = impedance_msg(self.model, ns, T.FRAME_CATHETER_BASE)
            self._published_model = self.model
        msg = self._msg
        set_stamp(msg.header.stamp, ns)
        msg.status = self.model.status
        self.pub.publish(msg)
        self.diag.count('published')

    def close(self) -> None:
        """Write the learned state (default identifier, state_file set)."""
        if self.sf is None:
            return
        try:
            written = self.sf.save(self.ident)
        except (OSError, ValueError) as exc:
            self.get_logger().error(f'could not write the learned state: {exc}')
            return
        if written:
            self.get_logger().info(f'learned state written to {written}')

    def _to_diag(self) -> None:
        d = self.diag
        status = self.ident.status
        d.set('identifier', self.kind)
        d.set('status', status)
        d.set('held_total', self.ident.n_held)
        if self.model is not None:
            d.set('model_valid', str(self.model.valid))
            d.set('model_kind', 'table' if self.model.kind else 'linear')
        for k in ('n_rejected', 'n_clipped', 'n_bursts', 'n_burst_samples', 'n_out_of_envelope'):
            if hasattr(self.ident, k):
                d.set(k[2:], getattr(self.ident, k))
        if self.sf is not None and self.sf.rejected:
            d.condition('state_file', WARN, self._sf_message)
        d.condition('no_model', WARN if self.model is None or not self.model.valid else 0,
                    f'no valid model yet (identifier {status})')
        now = self.get_clock().now().nanoseconds
        if status == 'ill_conditioned':
            if self._ill_since is None:
                self._ill_since = now
            stuck = (now - self._ill_since) * 1e-9 >= self.params['stuck_after']
            d.condition('held', ERROR if stuck else WARN,
                        f'model held: ill-conditioned data for '
                        f'{(now - self._ill_since) * 1e-9:.1f} s')
        else:
            self._ill_since = None
            d.condition('held', WARN if status not in ('ok', 'filling') else 0,
                        f'model held ({status})')


def fill_table_msg(msg, model) -> bool:
    """Write a table `Impedance` with an anchor into `msg`, an ImpedanceModel that
    `impedance_msg` made from an earlier such model with as many nodes, in place: the fields
    `impedance_msg(model)` would have (the header aside). False, and `msg` untouched, for
    anything else (no message yet, a linear model, no anchor, another node count, a value
    that is not finite or a sum of them that overflows): then `impedance_msg` converts it
    and refuses what it refuses. (A new message per model cost ~70 us; this ~10 us.)"""
    S = model.S
    a = model.anchor
    if (msg is None or S is None or a is None or not msg.has_anchor
            or msg.kind != ImpedanceModel.KIND_TABLE):
        return False
    n = len(S)
    F, B, C = model.F, model.B, model.C
    if not (n == len(msg.s_table) == len(F) == len(B) == len(C)):
        return False
    scalars = (model.m, model.c, model.k, model.offset, model.x0, model.dx, model.sigma,
               model.v_s, model.beta)
    status = getattr(model, 'status', '')
    if not isinstance(status, str) or not math.isfinite(
            sum(scalars) + sum(a) + sum(S) + sum(F) + sum(B) + sum(C)):
        return False
    (msg.m, msg.c, msg.k, msg.offset, msg.x0, msg.dx, msg.sigma, msg.v_s,
     msg.beta) = (float(v) for v in scalars)
    msg.valid = bool(model.valid)
    msg.s_table, msg.f_table, msg.b_table, msg.c_table = S, F, B, C
    msg.status = status
    (msg.anchor_x, msg.anchor_xd, msg.anchor_xdd, msg.anchor_z1, msg.anchor_z2,
     msg.anchor_f, msg.anchor_r) = (float(v) for v in a)
    return True


NODE_CLASS = ImpedanceIdentifierNode
main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())
