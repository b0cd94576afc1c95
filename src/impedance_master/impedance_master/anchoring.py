"""How the model's miss at its anchor reaches the master's state (issue 12, rounds 2-6).

Every model carries its `Anchor`: the slave's state and measured force at the sample it was
made at. `AnchorTerm` is what the renderer keeps of it: the anchor's depth, its friction
states and the model's miss there (rho = measured force - model force at the anchor).

* `anchored_force`: the anchored baseline, model + rho at any distance (model-mediated:
  the latest measured force plus the model's change from the anchor to the master's state).
* `supported_force`: the default IMA's 'local' anchoring weighed by the data support
  (third round): where the support c near the master's depth is thin the model is
  extended from the nearest seen depth (weight 1 - c; deeper with the steeper of the
  model's, at most MAX_MODEL_SLOPE (eighth round), and the MEASURED slope, fourth
  round) and the anchor's miss is kept with weight (1 - c)^2; with full support the miss
  fades with the depth difference and at a reversal; where the master turns outward at
  depths the slave has only moved inward at, the flip of the friction keeps the elastic
  share the measured force's growth in depth shows (`elastic_keep`, sixth round).

The model is evaluated with the friction states given (`Impedance.force_z`), also for a
stateless model (sigma 0, tenth round): `Impedance.force` takes the direction of x' there,
which made the split into the anchor's friction direction (hold) and its change (flip)
void, flip 0, so the elastic share never acted for it.

Pure functions of (model, friction states, master state, anchor term, support): the
renderer evaluates them on the master's state, the online score (`scoring`) on the
slave's later samples with the support it had then. No rclpy, no numpy.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional

from impedance_master.impedance import Impedance
from impedance_master.support import HINGE_F, SLOPE_STEP, DepthSlope, ElasticShare, Support


#: the share of the anchor's miss kept after a full reversal of the friction direction
#: (0.5, to keep a direction-independent miss such as breathing, screened worse in the
#: fifth round: README, Benchmark)
REVERSAL_KEEP = 0.0


#: N, the force at the edge of the data within which its sign (which way the model is
#: extended deeper) is blended: the sensor noise's level
SIGN_BAND = 0.01


class AnchorTerm(NamedTuple):
    """The renderer's view of a model's anchor: depth x (m), friction states z1, z2 there,
    and the model's miss rho (N) there."""
    x: float
    z1: float
    z2: float
    rho: float


def anchor_term(model: Impedance, anchoring: str) -> Optional[AnchorTerm]:
    """The `AnchorTerm` of a model's anchor (None if it has none): rho is the measured force
    minus the model's at the anchor ('full', 'local') or the identifier's low-passed
    residual there ('residual')."""
    a = model.anchor
    if a is None:
        return None
    if anchoring in ('full', 'local'):
        rho = a.f - model.force(a.x, a.xd, a.xdd, (a.z1, a.z2))
    else:
        rho = a.r
    return AnchorTerm(a.x, a.z1, a.z2, rho)


def anchored_force(m: Impedance, z, x: float, xd: float, xdd: float, a: AnchorTerm) -> float:
    """The anchored baseline at the master's state: the model plus its miss at the anchor."""
    return m.force_z(x, xd, xdd, z) + a.rho


def measured_slope(depth_slope: Optional[DepthSlope], max_slope: float, slope: float,
                   pushing: bool, max_model_slope: float = math.inf) -> float:
    """The steeper of the model's slope at the edge of its data (its tables flatten
    toward their priors there), at most `max_model_slope` in magnitude (eighth round:
    a steeper model slope is its fit of a local bump, not data), and the measured one
    (`DepthSlope`, inserting if `pushing`), at most max_slope."""
    slope = min(max_model_slope, max(-max_model_slope, slope))
    if depth_slope is None:
        return slope
    b = depth_slope.slope(1.0 if pushing else -1.0)
    if b is None:
        return slope
    if pushing:
        return max(slope, min(b, max_slope))
    return min(slope, max(b, -max_slope))


def elastic_keep(m: Impedance, x: float, za, sup: Support, elastic: ElasticShare,
                 gain: float, square: bool = False, hinge_gain: float = 0.0,
                 hinge_f: float = HINGE_F) -> float:
    """The factor (in [0, 1]) of the model's flip of the friction kept where the master
    turns outward at a depth the slave has not moved outward at (sixth round): the elastic
    part of the inserting force (a wall) does not reverse. The model already keeps its
    static force there (f(x, z = 0)); where `gain` x the measured elastic estimate
    (`ElasticShare`) of its inserting force f_ins is larger, the flip is cut so that the
    force left after a full reversal keeps that estimate, weighed by how unseen the outward
    direction is there (n_half / (n + n_half) of the outward anchors near x). With
    `hinge_gain` > 0 (seventeenth round; the renderer passes 0.7) the estimate is at least
    hinge_gain x the fitted wall's force k (x - x_w)+ (`ElasticShare.hinge`, F ratio
    `hinge_f`)."""
    n = sup.count(x, -1.0)
    w = sup.n_half / (n + sup.n_half)
    f_ins = m.force_z(x, 0.0, 0.0, za)
    e_model = m.force_z(x, 0.0, 0.0, (0.0, 0.0))
    fr = f_ins - e_model
    e_est = gain * elastic.share(x, f_ins) * f_ins
    if square:
        e_est = max(e_est, elastic.square_excess(x, f_ins))
    if hinge_gain > 0.0:
        h = elastic.hinge(hinge_f)
        if h is not None:
            e_est = max(e_est, hinge_gain * h.k * max(0.0, x - h.x_w))
    if not (fr > 0.0 and e_est > e_model):
        return 1.0
    return 1.0 - w * min(1.0, (e_est - e_model) / fr)


def supported_force(m: Impedance, z, x: float, xd: float, xdd: float, a: AnchorTerm,
                    anchor_length: float, sup: Support, depth_slope: Optional[DepthSlope],
                    max_slope: float, elastic: Optional[ElasticShare] = None,
                    elastic_gain: float = 0.0, max_model_slope: float = math.inf,
                    square: bool = False, hinge_gain: float = 0.0,
                    hinge_f: float = HINGE_F) -> float:
    """'local' anchoring where the model has data; beyond its data (the support `c` near x
    is thin) the model's tables are its priors' guess: extend the model from the nearest
    depth with data instead (weight 1 - c) and keep more of the anchor's measured force
    (weight (1 - c)^2): toward the anchored baseline. z: the friction states at x.
    Deeper than the data the model's own slope counts up to `max_model_slope` N/m."""
    za = (a.z1, a.z2)
    hold = m.force_z(x, xd, xdd, za)          # the anchor's direction of friction
    flip = m.force_z(x, xd, xdd, z) - hold    # the model's change of direction
    if elastic is not None and flip < 0.0 and a.z1 > 0.0:
        flip *= elastic_keep(m, x, za, sup, elastic, elastic_gain, square, hinge_gain,
                             hinge_f)
    c = sup.anywhere(x)
    lo, hi = sup.bracket(x) if c < 1.0 else (None, None)
    if lo is not None and hi is not None:
        if lo != hi:        # a gap between seen depths: the model's values at its edges
            flo = m.force_z(lo, xd, xdd, za)
            ext = flo + (m.force_z(hi, xd, xdd, za) - flo) * (x - lo) / (hi - lo)
            hold += (1.0 - c) * (ext - hold)
    elif hi is not None:
        # shallower than the data: in proportion to the depth (friction and drag grow
        # with the inserted length from 0)
        ext = m.force_z(hi, xd, xdd, za) * max(0.0, x) / hi
        hold += (1.0 - c) * (ext - hold)
    elif lo is not None:
        # deeper: the slope over SLOPE_STEP inside the data, never toward a smaller
        # |force| (friction grows with the length, a wall with the depth); where the
        # force at the edge is within SIGN_BAND of 0 its sign is unknown: the two
        # extensions are blended by it (a hard switch jumped as it crossed 0)
        fs = m.force_z(lo, xd, xdd, za)
        model_slope = (fs - m.force_z(lo - SLOPE_STEP, xd, xdd, za)) / SLOPE_STEP
        u = min(1.0, max(0.0, 0.5 + 0.5 * fs / SIGN_BAND))
        ext = fs
        if u > 0.0:
            ext += u * max(0.0, measured_slope(depth_slope, max_slope, model_slope,
                                               True, max_model_slope)) * (x - lo)
        if u < 1.0:
            ext += (1.0 - u) * min(0.0, measured_slope(depth_slope, max_slope, model_slope,
                                                       False, max_model_slope)) * (x - lo)
        hold += (1.0 - c) * (ext - hold)
    d = abs(x - a.x)
    g = (math.exp(-d / anchor_length) if d else 1.0)
    g *= max(REVERSAL_KEEP, 1.0 - 0.5 * abs(z[0] - a.z1))
    g = 1.0 - (1.0 - (1.0 - c) ** 2) * (1.0 - g)
    return hold + flip + a.rho * g
