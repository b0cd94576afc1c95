"""Master-side force rendering: impedance matching (IMA, thesis Eq. 35) and direct force
reflection (DFR, the thesis's baseline), both fail-safe (`safety.SafeOutput`).

`ImaRenderer` evaluates the latest environment model on the master's LOCAL trajectory, so
the feedback neither waits for nor stalls with the network. A new model never kicks the
operator's hand: at a switch the difference between the old and the new model at the
current state is taken up by a bumpless-transfer term that decays with `blend_time`
(the rendered force is continuous across switches), and optionally the output slews at
most `max_rate` N/s. The renderer owns the friction states of table models, driven by the
master's own position.

What it refuses, and what then reaches the hand:

* a model that is not valid (identifier warming up) or outside the `envelope`
  (`envelope.ModelEnvelope`: m = 1e308, k = 1e300, a tampered state): refused, counted
  (`n_ignored`, `n_refused`), the current model stays in use (an invalid model that
  carries an anchor before any model is in use, the identifier's 'filling' models, is not
  rendered either: its anchor, inside the envelope, is kept as where the slave was and
  counted with the first model, `n_pre_anchors`);
* a master state that is not finite or outside the state box (`state_box`: the envelope's
  workspace with margins, default x in [-0.07, 0.25] m, |x'| <= 1 m/s, |x''| <= 100
  m/s^2; x = -1.7e308 is not a hand): counted (`n_bad_input`), the FALLBACK holds the last
  safe force and ramps it to 0 N over `fallback_time`;
* a non-finite or absurd intermediate (model evaluation, bumpless term, passivity energy):
  the model that produced it is DROPPED (`n_dropped`), the intermediate reset, fallback;
* in every case the output is finite and within [-limit, limit] (`safety`); the renderer
  recovers by itself: good input with a model in use, or the next accepted model, takes
  over from the fallback's current value, the difference decaying with
  max(blend_time, RECOVER_TIME = 50 ms) (no step at the hand, even with blend_time 0).

`DfrRenderer` returns the last received slave force (held during outages); a force that is
not finite or above the envelope's max_force is refused (counted), the last one is kept.

`limit`, `max_rate`, `blend_time`, `passivity` and `fallback_time` are runtime-settable
(validated; applied from the next call). `status()` -> `safety.RendererStatus` for
diagnostics.
"""
from __future__ import annotations

import math
from collections import deque
from typing import Optional, Tuple

from catheter_common.checks import nonneg, positive
from impedance_master.envelope import DEFAULT_ENVELOPE, ModelEnvelope
from impedance_master.impedance import FrictionState, Impedance, steady_states
from impedance_master.safety import (ERROR, OK, SAFE_MAX_RATE, WARN,  # noqa: F401
                                    RendererStatus, SafeOutput, check_number)
from impedance_master.anchoring import (AnchorTerm, anchor_term, anchored_force,
                                       supported_force)
from impedance_master.scoring import SCORE_LAG, SCORE_RATE, OnlineScore
from impedance_master.support import (ELASTIC_GAIN, ELASTIC_SQUARE, HINGE_F,  # noqa: F401
                                     HINGE_GAIN,
                                     MAX_MODEL_SLOPE, MAX_SLOPE, SLOPE_LENGTH, SLOPE_STEP,
                                     SQUARE_BAND, SQUARE_SIGMAS, SUPPORT_HALF,
                                     SUPPORT_WIDTH, DepthSlope, ElasticShare, Support)

ANCHORING = ('none', 'full', 'residual', 'local')
#: m, default reach in depth of the 'local' anchor correction (see ImaRenderer)
LOCAL_ANCHOR_LENGTH = 0.005
#: s, smallest time constant of the take-over from the fallback to the model's force
RECOVER_TIME = 0.05
#: s, while the model is held (a link outage) the anchor's miss moves over this time from
#: the latest sample's to the identifier's low-passed one (and back after; sixth round)
HELD_LOWPASS = 0.3
#: anchors of invalid ('filling') models kept before the first model (the latest; 10 s at
#: the identifier's 50 models per second)
MAX_PRE_ANCHORS = 500


def _same(a: Impedance, b: Optional[Impedance]) -> bool:
    """True if b is the same model as a (same object or same values)."""
    if b is None or a is b:
        return b is not None
    return (a.m == b.m and a.c == b.c and a.k == b.k and a.offset == b.offset
            and a.valid == b.valid and a.sigma == b.sigma and a.S == b.S and a.F == b.F
            and a.B == b.B and a.C == b.C and a.x0 == b.x0 and a.dx == b.dx
            and a.anchor == b.anchor)


def _of_output(name: str) -> property:
    """A runtime parameter of the safe output stage (SafeOutput validates it), read and set
    through the renderer."""
    return property(lambda self: getattr(self._out, name),
                    lambda self, value: setattr(self._out, name, value))


class _Rendered:
    """What both renderers share: the safe output stage and its runtime parameters."""

    _out: SafeOutput
    stale_time: float

    limit = _of_output('limit')
    max_rate = _of_output('max_rate')
    fallback_time = _of_output('fallback_time')

    @property
    def n_clamped(self) -> int:
        return self._out.n_clamped

    @property
    def in_fallback(self) -> bool:
        return self._out.in_fallback


class ImaRenderer(_Rendered):
    """Impedance-matching renderer: f_d from the latest model and the local trajectory.

    Args:
        limit: N, safe output limit (|f_d| <= limit).
        blend_time: s, time constant of the bumpless transfer at a model switch (0: jump).
            Every switch is bumpless, the first one too: it blends in from the force
            rendered before (0 N), so the first model does not step the operator's hand.
        max_rate: N/s, slew-rate limit of the output (> 0; default inf: none; the nodes use
            `SAFE_MAX_RATE` as a safety net).
        dt: s, the call period (1 kHz loop), used by blending, slew limiting and timers.
        passivity: add the time-domain passivity controller (TDPA, Ryu & Hannaford): the
            observer E = sum f x' dt is the energy the operator has put into the rendered
            environment; when it would go negative (the model, e.g. a negative damping or a
            switch, returned more than it received), a damping alpha x' with
            alpha = -E / (dt x'^2) (at most max_damping N s/m) dissipates the excess.
        envelope: the `ModelEnvelope` models must satisfy (None: the default).
        fallback_time: s, the fallback's ramp from the held force to 0 N (default 0.5).
        stale_time: s, a model not received again for longer is reported 'held' (WARN).
        state_box: (x_lo, x_hi, max_speed, max_accel) of acceptable master states (None:
            the envelope's workspace with margins, see module doc).
        anchoring: how the model's miss at its anchor (the slave's latest sample: measured
            force minus the model there) enters: 'local' (default) the model plus that miss,
            fading with the distance in depth from the anchor (exp(-d / anchor_length)) and
            with the change of the friction direction state from the anchor's (to half at
            a full reversal): the latest measurement corrects the model where the
            catheter is near the anchor's depth and direction, and the model alone speaks
            for the changes it has data for; 'none' the model alone; 'full' (the
            anchored baseline: the anchor's force plus the model's change from the anchor
            state to the master's, at any distance unless anchor_length is given);
            'residual' (the model plus the identifier's low-passed residual at the anchor,
            fading with distance over `anchor_length` m).
        anchor_length: m (None: LOCAL_ANCHOR_LENGTH = 5 mm for 'local', inf otherwise).
        support_half: with 'local' anchoring, weigh the model by its data support
            (third round of issue 12; None: off, the second round's 'local'): the
            renderer counts the anchors of the models it receives (the slave's samples,
            `support.Support`) over depth; `support_half` anchors near a depth give a
            support c of 1/2 there (c = n / (n + support_half)). Where c is thin the
            model's tables are its priors' guess (beyond the deepest point reached, above
            the shallowest): the model is extended from the nearest depth with data
            instead (shallower: in proportion to the depth; deeper: with the slope found
            there, never toward a smaller |force|), with weight 1 - c, and the anchor's
            miss is kept with weight (1 - c)^2 (toward the anchored baseline: the latest
            measured force plus the model's change).
        support_width: m, reach in depth of one anchor's support (triangular kernel).
        slope_length: m, with the support weighing: deeper than the data the model is
            extended with the steeper of its own slope and the MEASURED force's slope
            over the last `slope_length` of the slave's path (`support.DepthSlope`;
            fourth round of issue 12), at most `max_slope` N/m. None: the model's slope
            (the third round). Between two seen depths (a gap in the data) the model is
            interpolated between its values there (fifth round; the extension from the
            NEAREST seen depth jumped at the gap's middle: `anchoring.supported_force`).
        max_model_slope: N/m, with the support weighing: deeper than the data the MODEL's
            own slope at the edge counts at most this steeply (eighth round of issue 12;
            default MAX_MODEL_SLOPE = 10 N/m): a steeper rise there is the tables' fit
            of a local bump (a stenosis the slave stopped on threw 0.5 N ahead); the
            measured slope, up to `max_slope`, still extends a wall. None: uncapped (the
            seventh round).
        score_memory: s, with the support weighing: blend the anchored baseline into the
            rendered force by the online score's least-squares weight
            (`scoring.OnlineScore`, forgetting time constant `score_memory`, horizon
            `score_lag` s, weight slew `score_rate` 1/s; fifth round). None (default):
            off; it did not pay on the seen worlds (README, Benchmark).
        elastic_gain: with the support weighing: where the master turns outward at depths
            the slave has only moved inward at (a first reversal), the model's flip of the
            friction keeps `elastic_gain` x the elastic share of the inserting force that
            the MEASURED force's growth in depth shows (`support.ElasticShare`: the force
            above the least-squares line through the entry fitted to the forces met at
            least 15 mm shallower; a wall does not reverse, friction does), where that is
            more than the model's own static force there (`anchoring.elastic_keep`, sixth
            round of issue 12; default 0.5: the line through the entry reads a friction
            growing faster than the length as elastic too). None: off (the fifth round).
        elastic_square: with `elastic_gain`: the first outward reversal keeps at least the
            part of the inserting force above the square-law friction c x^2 fitted to the
            forces met at least 15 mm shallower (`ElasticShare.square_excess`: the
            steepest friction growth of the drawn vessels, so what is above it is a wall's;
            thirteenth round of issue 12). Default True (ELASTIC_SQUARE) since the
            fourteenth round, with `square_sigmas` 2: alone (the thirteenth) it gained three
            stiff_wall worlds and lost one to the anchored baseline, at a shallow depth where
            the square law fitted to forces at the noise's level read the breathing as a
            wall (README, Benchmark).
        square_band, square_sigmas: with `elastic_square`: the force above the square law is
            counted only above a band of the forces' disturbances, `square_band` N plus
            `square_sigmas` x the rms scatter of the shallow forces about the law
            (`ElasticShare.square_scatter`: sensor noise, cardiac and breathing, the law's
            misfit; fourteenth round of issue 12). Defaults SQUARE_BAND = 0 N,
            SQUARE_SIGMAS = 2.
        held_lowpass: s, with the support weighing: while the model is held (not received
            for `stale_time`: a link outage) the anchor's miss is moved, linearly over
            `held_lowpass` s, from the latest sample's (measured force minus the model:
            one sample's sensor noise, 5-20 mN, held for the whole outage) to the
            identifier's low-passed residual at the anchor (`Anchor.r`, 0.1 s), and back
            over the same time once models arrive again (continuous: a switch's bumpless
            term sees the same blend before and after; sixth round of issue 12; default
            HELD_LOWPASS = 0.3 s). None: off (the fifth round).
        elastic_hinge, hinge_f: with `elastic_gain`: the first outward reversal keeps at
            least `elastic_hinge` x the force of a wall fitted to the inward forces,
            k (x - x_w)+ (`wall_fit.fit_hinge`: friction linear and square in the length,
            a linear wall with its damper; accepted at an F ratio of at least `hinge_f`,
            default HINGE_F = 300; seventeenth round of issue 12: a stiff wall entered
            before the elastic share's 15 mm margin read it was flipped whole). Default
            HINGE_GAIN = 0.7; None: off (the sixteenth round).
        pre_anchors: keep the anchors of invalid models offered before the first model
            (the default identifier's 'filling' models, one per 20 ms of its first second
            of motion) and count them with the first model's anchor in the support, the
            measured slope and the elastic share (default True; nineteenth round of issue
            12: without them the renderer's data began about 1.5 s into the run, often
            past a wall's onset, and the wall fit could not see it). False: they are
            ignored like any invalid model (`n_ignored`), the eighteenth round.
    Attributes: `model` (in use), `n_switches`, `n_ignored` (invalid models), `n_refused`
    (outside the envelope), `n_pre_anchors` (anchors of invalid models kept before the
    first model: the support, measured slope and elastic share count them with the first
    model, the nineteenth round of issue 12), `n_dropped` (dropped after a non-finite
    evaluation),
    `n_bad_input`, `n_clamped`, `energy` (J, observer), `n_passivity` (steps with added
    damping), `in_fallback`.
    """

    def __init__(self, limit: float = 2.0, blend_time: float = 0.05,
                 max_rate: float = math.inf, dt: float = 1e-3, passivity: bool = False,
                 max_damping: float = 50.0, envelope: Optional[ModelEnvelope] = None,
                 fallback_time: float = 0.5, stale_time: float = 0.1,
                 state_box: Optional[Tuple[float, float, float, float]] = None,
                 anchoring: str = 'local', anchor_length: Optional[float] = None,
                 support_half: Optional[float] = SUPPORT_HALF,
                 support_width: float = SUPPORT_WIDTH,
                 slope_length: Optional[float] = SLOPE_LENGTH, max_slope: float = MAX_SLOPE,
                 max_model_slope: Optional[float] = MAX_MODEL_SLOPE,
                 score_memory: Optional[float] = None, score_lag: float = SCORE_LAG,
                 score_rate: float = SCORE_RATE,
                 elastic_gain: Optional[float] = ELASTIC_GAIN,
                 held_lowpass: Optional[float] = HELD_LOWPASS,
                 elastic_square: bool = ELASTIC_SQUARE, square_band: float = SQUARE_BAND,
                 square_sigmas: float = SQUARE_SIGMAS,
                 elastic_hinge: Optional[float] = HINGE_GAIN,
                 hinge_f: float = HINGE_F, pre_anchors: bool = True):
        self._out = SafeOutput(limit, max_rate, dt, fallback_time)
        self.dt = self._out.dt
        self.blend_time = blend_time
        self.passivity = passivity
        self.max_damping = positive('max_damping', max_damping)
        if envelope is not None and not isinstance(envelope, ModelEnvelope):
            raise ValueError(f'envelope must be a ModelEnvelope, got {type(envelope).__name__}')
        self.envelope = envelope if envelope is not None else DEFAULT_ENVELOPE
        self.stale_time = nonneg('stale_time', stale_time)
        env = self.envelope
        box = state_box if state_box is not None else (
            env.x_lo - 0.05, env.x_hi + 0.05, 10.0 * env.max_speed, 50.0 * env.max_accel)
        try:
            lo, hi, vmax, amax = (float(v) for v in box)
        except (TypeError, ValueError):
            raise ValueError(f'state_box must be (x_lo, x_hi, max_speed, max_accel), '
                             f'got {state_box!r}') from None
        if not (lo < hi and vmax > 0.0 and amax > 0.0):
            raise ValueError(f'state_box must have x_lo < x_hi and positive limits, '
                             f'got {state_box!r}')
        self.state_box = (lo, hi, vmax, amax)
        if anchoring not in ANCHORING:
            raise ValueError(f'anchoring must be one of {ANCHORING}, got {anchoring!r}')
        self.anchoring = anchoring
        if anchor_length is None:
            anchor_length = LOCAL_ANCHOR_LENGTH if anchoring == 'local' else math.inf
        self.anchor_length = float(anchor_length) if anchor_length == math.inf else \
            positive('anchor_length', anchor_length)
        self.support: Optional[Support] = None
        self.depth_slope: Optional[DepthSlope] = None
        self.max_slope = positive('max_slope', max_slope)
        self.max_model_slope = (math.inf if max_model_slope is None
                                else positive('max_model_slope', max_model_slope))
        self.score: Optional[OnlineScore] = None
        self.elastic: Optional[ElasticShare] = None
        if support_half is not None and anchoring == 'local':
            self.support = Support(lo, hi, support_width, support_half)
            if elastic_gain is not None:
                self.elastic = ElasticShare(lo, hi, square_band=square_band,
                                            square_sigmas=square_sigmas)
            if slope_length is not None:
                self.depth_slope = DepthSlope(positive('slope_length', slope_length))
            if score_memory is not None:
                self.score = OnlineScore(
                    Support(lo, hi, support_width, support_half),
                    None if slope_length is None else DepthSlope(slope_length),
                    self.anchor_length, self.max_slope, self._out.dt, score_lag,
                    score_memory, score_rate)
        self.held_lowpass = (None if held_lowpass is None
                             else positive('held_lowpass', held_lowpass))
        self._rho_lp = 0.0
        self._q = 0.0
        self.elastic_gain = (0.0 if elastic_gain is None
                             else positive('elastic_gain', elastic_gain))
        if not isinstance(elastic_square, bool):
            raise ValueError(f'elastic_square must be a bool, got {elastic_square!r}')
        self.elastic_square = elastic_square
        nonneg('square_band', square_band)
        nonneg('square_sigmas', square_sigmas)
        self.elastic_hinge = (0.0 if elastic_hinge is None
                              else positive('elastic_hinge', elastic_hinge))
        self.hinge_f = positive('hinge_f', hinge_f)
        self.model: Optional[Impedance] = None
        self._pending: Optional[Impedance] = None
        self._bump = 0.0
        self._state: Optional[FrictionState] = None
        self._z = (0.0, 0.0)
        self._rho = 0.0
        self._rho_set = False
        self._term = AnchorTerm(0.0, 0.0, 0.0, 0.0)
        self._xa = 0.0
        self._za = 0.0
        self._za2 = 0.0
        self._age = math.inf
        self._refused_since_accept = False
        self._bad_now = False
        self.n_switches = 0
        self.n_ignored = 0
        if not isinstance(pre_anchors, bool):
            raise ValueError(f'pre_anchors must be a bool, got {pre_anchors!r}')
        self.pre_anchors = pre_anchors
        self.n_pre_anchors = 0
        self._pre: deque = deque(maxlen=MAX_PRE_ANCHORS)
        self.n_refused = 0
        self.n_dropped = 0
        self.n_bad_input = 0
        self.energy = 0.0
        self.n_passivity = 0
        self.last_reason = ''

    # ------------------------------------------------------------------ parameters
    @property
    def blend_time(self) -> float:
        return self._blend_time

    @blend_time.setter
    def blend_time(self, value) -> None:
        self._blend_time = nonneg('blend_time', value)
        self._decay = math.exp(-self._out.dt / self._blend_time) if self._blend_time > 0 else 0.0
        self._bump_decay = self._decay

    @property
    def passivity(self) -> bool:
        return self._passivity

    @passivity.setter
    def passivity(self, value) -> None:
        if not isinstance(value, (bool, int)):
            raise ValueError(f'passivity must be a bool, got {value!r}')
        self._passivity = bool(value)

    # ------------------------------------------------------------------ models
    def set_impedance(self, imp: Impedance) -> bool:
        """Offer a new model; returns True if it is (or already was) in use or pending,
        False if refused (invalid, or outside the envelope: the current model stays).
        The same model again only refreshes its age (the link is alive)."""
        if not isinstance(imp, Impedance):
            raise ValueError(f'imp must be an Impedance, got {type(imp).__name__}')
        if not imp.valid:
            if (self.pre_anchors and imp.anchor is not None and self.model is None
                    and self._pending is None):
                self._keep_pre_anchor(imp)
            else:
                self.n_ignored += 1
            return False
        if _same(imp, self._pending) or (self._pending is None and _same(imp, self.model)):
            self._age = 0.0
            return True
        why = self.envelope.check(imp)
        if why is not None:
            self.n_refused += 1
            self._refused_since_accept = True
            self.last_reason = f'model refused: {why}'
            return False
        self._pending = imp
        self._age = 0.0
        self._refused_since_accept = False
        return True

    def _keep_pre_anchor(self, imp: Impedance) -> None:
        """Before any model: keep the anchor of an invalid model (the identifier's
        'filling' models: where the slave was and the force it met) if it is new and inside
        the envelope; counted with the first model (`_count_anchor`)."""
        a = imp.anchor
        if self._pre and self._pre[-1] == a:
            return                              # the same model again (re-sent)
        why = self.envelope.check(imp)
        if why is not None:
            self.n_refused += 1
            self.last_reason = f'model refused: {why}'
            return
        self._pre.append(a)
        self.n_pre_anchors += 1

    def _count_anchor(self, new: Impedance, a) -> None:
        """Count anchor `a` (the slave's sample) where the slave has measured: the support,
        the measured slope over depth and the elastic share (its force less `new`'s
        velocity terms there)."""
        self.support.add(a.x, a.xd)
        if self.depth_slope is not None:
            self.depth_slope.add(a.x, a.xd, a.f, a.z1)
        if self.elastic is not None:
            za = (a.z1, a.z2)
            self.elastic.add(a.x, a.xd, a.f - new.force_z(a.x, a.xd, a.xdd, za)
                             + new.force_z(a.x, 0.0, 0.0, za), a.z1)

    def _eval(self, x: float, xd: float, xdd: float) -> float:
        m = self.model
        if self.support is not None and self._rho_set:
            return self._eval_supported(x, xd, xdd)
        f = m.force(x, xd, xdd, self._z if self._state is not None else None)
        if self._rho:
            d = abs(x - self._xa)
            g = (math.exp(-d / self.anchor_length) if d else 1.0)
            if self.anchoring == 'local':     # ... and with the change of direction
                z1 = self._z[0] if self._state is not None else math.tanh(xd / m.v_s)
                g *= max(0.0, 1.0 - 0.5 * abs(z1 - self._za))
            f += self._rho * g
        return f

    def _eval_supported(self, x: float, xd: float, xdd: float) -> float:
        """`anchoring.supported_force` on the master's state, blended toward the anchored
        baseline by the online score's weight (if scoring)."""
        m = self.model
        z = self._z if self._state is not None else steady_states(xd, m.v_s, m.beta)
        term = self._term
        if self._q > 0.0:
            term = term._replace(rho=term.rho + self._q * (self._rho_lp - term.rho))
        f = supported_force(m, z, x, xd, xdd, term, self.anchor_length, self.support,
                            self.depth_slope, self.max_slope, self.elastic, self.elastic_gain,
                            self.max_model_slope, self.elastic_square, self.elastic_hinge,
                            self.hinge_f)
        w = self.score.weight * self.support.anywhere(x) if self.score is not None else 0.0
        if w > 0.0:
            f += w * (anchored_force(m, z, x, xd, xdd, term) - f)
        return f

    def _switch(self, x: float, xd: float, xdd: float) -> None:
        new = self._pending
        self._pending = None
        key = new.state_key()
        if key is None:
            self._state = None
        elif self._state is None or self._state.key() != key:
            st = new.make_state()
            z0 = self._z if self._state is not None else st.steady(xd)
            st.reset(x, *z0)
            self._state = st
            self._z = z0
        if self.model is not None and not self._out.in_fallback:
            old_f = self._eval(x, xd, xdd)
        else:       # the first model, or after a fault: blend in from what is rendered
            old_f = self._out.last
        a = new.anchor
        self._rho = 0.0
        self._rho_set = False
        if self.anchoring != 'none' and a is not None:
            self._rho_set = True
            term = self._term = anchor_term(new, self.anchoring)
            self._xa, self._za, self._za2, self._rho = term
            self._rho_lp = a.r
            if self.support is not None:
                while self._pre:                # where the slave was before the first model
                    self._count_anchor(new, self._pre.popleft())
                self._count_anchor(new, a)
                if self.score is not None:
                    self.score.observe(new, term, a)
        self._pre.clear()                       # counted above, or not used
        self.model = new
        self.n_switches += 1
        if self._out.in_fallback:       # a good model after a fault: take over bumplessly
            self._take_over(old_f - self._eval(x, xd, xdd))
        elif self._blend_time > 0.0:    # the old-new difference decays with blend_time
            self._bump += old_f - self._eval(x, xd, xdd)
            self._bump_decay = self._decay

    def _take_over(self, bump: float) -> None:
        """Leave the fallback: the difference to the fallback's force decays with
        RECOVER_TIME (whatever blend_time is: a recovery never steps the hand)."""
        self._bump = bump
        self._bump_decay = math.exp(-self._out.dt / max(self._blend_time, RECOVER_TIME))
        self._out.recover()

    def _drop(self, why: str) -> None:
        """A non-finite or absurd intermediate: drop the model, reset the intermediates."""
        self.n_dropped += 1
        self.last_reason = f'model dropped: {why}'
        self.model = None
        self._state = None
        self._bump = 0.0
        self.energy = 0.0
        self._out.fault()

    # ------------------------------------------------------------------ output
    def desired_force(self, x, xd, xdd) -> float:
        """Desired force in N at the hand for the master state (x m, xd m/s, xdd m/s^2):
        always a finite float in [-limit, limit]. 0 until a valid model has arrived.
        Call once per control period `dt`. Non-numbers: ValueError naming the argument;
        non-finite or out-of-box numbers: bad input (fallback, see module doc)."""
        x = check_number('x', x)
        xd = check_number('xd', xd)
        xdd = check_number('xdd', xdd)
        self._age += self.dt
        lo, hi, vmax, amax = self.state_box
        if not (lo <= x <= hi and abs(xd) <= vmax and abs(xdd) <= amax):
            self.n_bad_input += 1
            self._bad_now = True
            self.last_reason = f'bad master state x={x!r} xd={xd!r} xdd={xdd!r}'
            self._out.fault()
            return self._out.output(0.0)
        self._bad_now = False
        self._xd = xd
        if self.score is not None:
            self.score.tick(self._age)
        if self.held_lowpass is not None:
            step = self.dt / self.held_lowpass
            self._q = (min(1.0, self._q + step) if self._age > self.stale_time
                       else max(0.0, self._q - step))
        if self._state is not None:
            self._z = self._state.update(x, xd)
        if self._pending is not None:
            self._switch(x, xd, xdd)
        if self.model is None:
            return self._out.output(0.0)
        f = self._eval(x, xd, xdd)
        if not (math.isfinite(f) and abs(f) < 1e3) or not math.isfinite(self._bump):
            self._drop(f'evaluation gave {f!r} (bump {self._bump!r})')
            return self._out.output(math.nan)
        if self._out.in_fallback:       # good input again with a model: take over bumplessly
            self._take_over(self._out.last - f)
        f += self._bump
        self._bump *= self._bump_decay
        out = self._out.output(f, self._passivity_step if self._passivity else None)
        if self._out.in_fallback:       # the passivity step was not finite
            self._drop(f'passivity gave a non-finite force (energy {self.energy!r})')
        elif self._passivity:
            self.energy += out * xd * self.dt
            if not math.isfinite(self.energy):
                self._drop(f'passivity energy {self.energy!r}')
        return out

    def _passivity_step(self, f: float) -> float:
        xd = self._xd
        e = self.energy + f * xd * self.dt
        if e < 0.0 and xd * xd > 1e-12:
            alpha = min(-e / (self.dt * xd * xd), self.max_damping)
            self.n_passivity += 1
            return f + alpha * xd
        return f

    # ------------------------------------------------------------------ health
    def status(self) -> RendererStatus:
        """Health for diagnostics (see `safety.RendererStatus`)."""
        counters = dict(self._out.counters(), switches=self.n_switches, ignored=self.n_ignored,
                        refused=self.n_refused, dropped=self.n_dropped,
                        bad_input=self.n_bad_input, passivity_steps=self.n_passivity)
        if self._bad_now:
            level, state, msg = ERROR, 'bad_input', self.last_reason
        elif self._out.in_fallback:
            level, state, msg = ERROR, 'fallback', (
                f'fallback: holding and ramping to 0 N ({self.last_reason})')
        elif self.model is None and self._pending is None:
            level, state, msg = WARN, 'no_model', 'no valid model received yet: rendering 0 N'
        elif self._refused_since_accept:
            level, state, msg = WARN, 'refused', self.last_reason
        elif self._age > self.stale_time:
            level, state, msg = WARN, 'held', (
                f'model held: not received for {self._age:.2f} s')
        else:
            level, state, msg = OK, 'ok', 'rendering the latest model'
        return RendererStatus(level, state, msg, counters, self._age, self.limit)


class DfrRenderer(_Rendered):
    """Direct force reflection: the desired force is the last force received from the slave.

    Args: limit N, safe output limit; max_force N, forces above it are refused (default
    the envelope's max_force, 10 N); stale_time s (a force older is reported 'held');
    dt s (call period, for the age).
    """

    def __init__(self, limit: float = 2.0, max_force: Optional[float] = None,
                 stale_time: float = 0.1, dt: float = 1e-3):
        self._out = SafeOutput(limit, math.inf, dt, 0.0)
        self.max_force = positive('max_force', DEFAULT_ENVELOPE.max_force
                                  if max_force is None else max_force)
        self.stale_time = nonneg('stale_time', stale_time)
        self._f = 0.0
        self._age = math.inf
        self.n_updates = 0
        self.n_refused = 0
        self.last_reason = ''

    def set_force(self, f) -> bool:
        """New slave force in N; True if taken, False if refused (not finite, or above
        max_force in magnitude: the last force is kept). Non-numbers: ValueError."""
        f = check_number('f', f)
        if not (math.isfinite(f) and abs(f) <= self.max_force):
            self.n_refused += 1
            self.last_reason = f'force refused: {f!r}'
            return False
        self._f = f
        self._age = 0.0
        self.n_updates += 1
        return True

    def desired_force(self, *_state) -> float:
        """Desired force in N (the state arguments, if any, are ignored)."""
        self._age += self._out.dt
        return self._out.output(self._f)

    def status(self) -> RendererStatus:
        counters = dict(self._out.counters(), updates=self.n_updates, refused=self.n_refused)
        if self.n_updates == 0:
            level, state, msg = WARN, 'no_model', 'no force received yet: rendering 0 N'
        elif self._age > self.stale_time:
            level, state, msg = WARN, 'held', f'force held: not received for {self._age:.2f} s'
        else:
            level, state, msg = OK, 'ok', 'reflecting the latest force'
        return RendererStatus(level, state, msg, counters, self._age, self.limit)
