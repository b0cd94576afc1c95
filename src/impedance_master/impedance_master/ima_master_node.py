"""ROS 2 node `ima_master_node` (master side): renders the desired force for the haptic device.

Subscribes  master/command         catheter_interfaces/MasterCommand, the LOCAL master
                                   trajectory: position x m, velocity m/s, acceleration
                                   x'' m/s^2. QOS_FAST.
            master/link/impedance  catheter_interfaces/ImpedanceModel, the slave's model as
                                   delivered by the link. QOS_FAST.
            master/link/force      geometry_msgs/WrenchStamped, the slave's force as delivered
                                   (force.x N). QOS_FAST.
Publishes   master/rendered_force  geometry_msgs/WrenchStamped, force.x = desired force N
                                   (positive resists insertion), frame catheter_base; at
                                   `rate` Hz on the node clock while subscribed. QOS_FAST.
            /diagnostics           rendered, models received, bad messages, the renderer's
                                   counters (renderer.*), age of the last command; conditions:
                                   the renderer's status (no model yet, model held = link
                                   outage, model refused: WARN; fallback, bad input: ERROR),
                                   no fresh command, output clamped (WARN) or not finite
                                   (ERROR), bad messages (WARN).
Topic names are relative (the node's namespace applies). Modes (parameter `mode`):
  ima         ImaRenderer with bumpless model switches, slew limiting and the time-domain
              passivity controller (project default);
  ima_thesis  ImaRenderer rendering only the linear part m x'' + c x' + k x + offset of the
              received model, switched at once (thesis Eq. 35), same clamp;
  dfr         DfrRenderer: the last force received (thesis baseline).
The published force is finite and within +-limit whatever the renderer returns (a non-finite
value is replaced by 0 N, counted, and raises an ERROR); `limit` applies from the next tick.
Thin: rendering is impedance_master.rendering.
"""
from __future__ import annotations

import math

from catheter_interfaces.msg import ImpedanceModel, MasterCommand
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node

from catheter_common import topics as T
from catheter_common.checks import finite
from catheter_common.diagnostics import ERROR, WARN, Diagnostics
from catheter_common.messages import impedance_fields, impedance_key, master_command_values
from catheter_common.outgoing import WrenchOut
from catheter_common.params import NodeParams, Param, table
from catheter_common.qos import QOS_FAST
from catheter_common.ros_node import clock_ns, node_main
from impedance_master.impedance import Impedance
from impedance_master.rendering import SAFE_MAX_RATE, DfrRenderer, ImaRenderer

MODES = ('ima', 'ima_thesis', 'dfr')
#: the renderer's status levels ('ok', 'warn', 'error') as diagnostics levels
_LEVELS = {'ok': 0, 'warn': WARN, 'error': ERROR}

PARAMS = table(
    Param('mode', 'ima', 'ima (default model, bumpless), ima_thesis (linear Eq. 35) or dfr '
          '(direct force reflection)', choices=MODES),
    Param('rate', 1000.0, 'rendering rate, Hz', 10.0, 5000.0),
    Param('limit', 2.0, 'safe force limit |f_d|, N (applies from the next tick)', 0.01, 20.0,
          dynamic=True),
    Param('blend_time', 0.05, 'bumpless model switch time constant, s (mode ima; applies '
          'from the next tick)', 0.0, 5.0, dynamic=True),
    Param('max_rate', SAFE_MAX_RATE, 'slew-rate limit of the desired force, N/s (mode ima; '
          '10 N/s: at most 0.01 N per 1 ms period)', 0.01, 1e6, dynamic=True),
    Param('passivity', True, 'time-domain passivity controller on the rendered model (mode '
          'ima)', dynamic=True),
    Param('fallback_time', 0.5, 'after a dropped model or bad input the renderer holds the '
          'last safe force and ramps it to 0 N over this time, s (mode ima)', 0.0, 10.0,
          dynamic=True),
    Param('stale_after', 0.1, 'feedback (model or force) older than this is reported as held '
          '(link outage), s', 0.001, 60.0, dynamic=True),
)
#: the renderer settings that only the default mode has (ima_thesis renders Eq. 35 as the
#: thesis does: no blending, no slew limit, no passivity controller)
_IMA_ONLY = ('blend_time', 'max_rate', 'passivity', 'fallback_time')


def set_core_limit(renderer, limit: float) -> bool:
    """Give the renderer the new limit if it takes one at run time (True); False if its
    limit is fixed at construction (then only the node's output clamp applies it)."""
    try:
        renderer.limit = limit
    except AttributeError:
        return False
    return True


class ImaMasterNode(Node):
    """Master-side renderer node (see module doc)."""

    PARAMS = PARAMS

    def __init__(self, **kwargs):
        super().__init__('ima_master_node', **kwargs)
        self.params = p = NodeParams(self, PARAMS, apply=self._apply_params)
        self.mode = p['mode']
        self.rate = p['rate']
        self.limit = p['limit']
        dt = 1.0 / self.rate
        if self.mode == 'dfr':
            self.renderer = DfrRenderer(limit=self.limit)
        elif self.mode == 'ima_thesis':
            self.renderer = ImaRenderer(limit=self.limit, blend_time=0.0, max_rate=1e6, dt=dt)
        else:
            self.renderer = ImaRenderer(limit=self.limit, blend_time=p['blend_time'],
                                        max_rate=p['max_rate'], dt=dt, passivity=p['passivity'],
                                        fallback_time=p['fallback_time'])
        self.renderer.stale_time = p['stale_after']
        self.state = None            # (x, xd, xdd) of the local trajectory
        self._t_state = None         # node-clock ns of the last command
        self._last_key = None        # impedance_key of the last model parsed
        self._last_imp = None
        self.diag = Diagnostics(self)
        for k in ('rendered', 'bad_messages', 'nonfinite_outputs', 'clamped_outputs'):
            self.diag.count(k, 0)
        self.pub = self.create_publisher(WrenchStamped, T.relative(T.MASTER_RENDERED_FORCE),
                                         QOS_FAST)
        self.create_subscription(MasterCommand, T.relative(T.MASTER_COMMAND), self._on_command,
                                 QOS_FAST)
        self.create_subscription(ImpedanceModel, T.relative(T.MASTER_LINK_IMPEDANCE),
                                 self._on_impedance, QOS_FAST)
        self.create_subscription(WrenchStamped, T.relative(T.MASTER_LINK_FORCE), self._on_force,
                                 QOS_FAST)
        # the 1 kHz render's own objects: one reused message (serialised at publish,
        # catheter_common.outgoing) and the node clock (the same object for the node's life)
        self._out = WrenchOut(T.FRAME_CATHETER_BASE)
        self._clock = self.get_clock()
        self._clock_ns = clock_ns(self._clock)
        self.timer = self.create_timer(dt, self._render)
        self.diag.add_updater(self._to_diag)
        self.get_logger().info(
            f'rendering {self.pub.topic_name} at {self.rate:g} Hz in mode {self.mode} '
            f'(limit {self.limit:g} N)')

    def _apply_params(self, changes, values) -> None:
        for k in _IMA_ONLY:
            if k in changes and self.mode != 'ima':
                raise ValueError(f'{k} applies in mode ima only (this node renders {self.mode})')
        for k in _IMA_ONLY:                    # the renderer validates (ValueError refuses)
            if k in changes:
                setattr(self.renderer, k, changes[k])
        if 'stale_after' in changes:
            self.renderer.stale_time = values['stale_after']
        if 'limit' in changes:
            self.limit = values['limit']
            set_core_limit(self.renderer, self.limit)

    def _now_ns(self) -> int:
        return self._clock_ns()

    def _on_command(self, msg: MasterCommand) -> None:
        try:
            x, xd, xdd, _rot = master_command_values(msg)
        except ValueError as exc:
            self.diag.bad_input('command', str(exc))
            return
        self.state = (x, xd, xdd)
        self._t_state = self._now_ns()
        self.diag.count('commands')

    def _on_impedance(self, msg: ImpedanceModel) -> None:
        if self.mode == 'dfr':
            self.diag.count('models_ignored_mode')
            return
        key = impedance_key(msg)
        if key == self._last_key:
            # the identifier re-sends a held model: offered again (no parsing), which tells
            # the renderer it is fresh
            self.diag.count('models_unchanged')
            self.renderer.set_impedance(self._last_imp)
            return
        try:
            imp = Impedance.from_fields(impedance_fields(msg))
        except ValueError as exc:
            self.diag.bad_input('impedance', str(exc))
            return
        if self.mode == 'ima_thesis' and imp.kind != 0:
            imp = Impedance(imp.m, imp.c, imp.k, imp.offset, imp.valid)
        self._last_key, self._last_imp = key, imp
        self.diag.count('models_received')
        pre = self.renderer.n_pre_anchors           # mode ima / ima_thesis: an ImaRenderer
        if not self.renderer.set_impedance(imp):
            if self.renderer.n_pre_anchors > pre:
                # the identifier's warm-up ('filling'): no model yet, its anchor is kept
                self.diag.count('models_filling')
                return
            self.diag.count('models_ignored_invalid')
            self.diag.event('model_invalid', WARN, 'models marked invalid by the identifier '
                            'are ignored (the previous model stays in use)')

    def _on_force(self, msg: WrenchStamped) -> None:
        if self.mode != 'dfr':
            self.diag.count('forces_ignored_mode')
            return
        try:
            f = finite('force.x', msg.wrench.force.x)
        except ValueError as exc:
            self.diag.bad_input('force', str(exc))
            return
        self.renderer.set_force(f)
        self.diag.count('forces_received')

    def _render(self) -> None:
        if self.pub.get_subscription_count() == 0:
            return
        if self.mode == 'dfr':
            f = self.renderer.desired_force()
        elif self.state is None:
            f = 0.0
        else:
            try:
                f = self.renderer.desired_force(*self.state)
            except ValueError as exc:     # the renderer refused the state: render nothing
                self.diag.event('renderer_refused', ERROR, f'renderer refused the state: {exc}')
                f = 0.0
        ns = self._clock_ns()
        self.pub.publish(self._out.fill(ns, self._safe(f)))
        self.diag.count('rendered')

    def _safe(self, f) -> float:
        """The last line before the hand: finite and within +-limit."""
        f = float(f)
        if not math.isfinite(f):
            self.diag.count('nonfinite_outputs')
            self.diag.event('nonfinite_output', ERROR, f'renderer returned {f}: 0 N rendered',
                            hold=1.0)
            return 0.0
        lim = self.limit
        if f > lim or f < -lim:
            self.diag.count('clamped_outputs')
            self.diag.event('clamped', WARN, f'desired force clamped to +-{lim:g} N', hold=1.0)
            return lim if f > 0 else -lim
        return f

    def _conditions(self) -> None:
        """The renderer's own health (no model, model held = link outage, model refused,
        fallback) and the master command's age."""
        d = self.diag
        st = self.renderer.status()
        d.condition('renderer', _LEVELS.get(st.level, ERROR), f'{st.state}: {st.message}')
        d.set('renderer_state', st.state)
        for k, v in sorted(st.counters.items()):
            d.set('renderer.' + k, v)
        now = self._now_ns()
        stale = self.params['stale_after'] * 1e9
        cmd_age = None if self._t_state is None else now - self._t_state
        d.condition('no_command', WARN if cmd_age is None or cmd_age > stale else 0,
                    'no master command yet' if cmd_age is None else
                    f'master command {cmd_age * 1e-9:.3f} s old')

    def _to_diag(self) -> None:
        r = self.renderer
        self._conditions()
        self.diag.set('mode', self.mode)
        self.diag.set('limit_n', float(self.limit))
        if isinstance(r, ImaRenderer):
            self.diag.set('has_model', str(r.model is not None))
            self.diag.set('passivity_energy_j', float(r.energy))
        if self._t_state is not None:
            self.diag.set('command_age_s', (self._now_ns() - self._t_state) * 1e-9)


NODE_CLASS = ImaMasterNode
main = node_main(NODE_CLASS)


if __name__ == '__main__':
    raise SystemExit(main())
