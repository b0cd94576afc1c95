"""What every node that holds a side of the simulated link shares (sim_slave_node: the
slave's side; impedance_master.sim_haptic_node: the master's): the link.* parameters and
their LinkConfig, the run time since the first timer tick (a clock jump back restarts the
run), and the link's counters and outage condition on /diagnostics.

For node modules (catheter_common.params declares ROS parameters); the link itself is
sim_slave.link.
"""
from __future__ import annotations

from typing import Optional, Sequence, Tuple

from catheter_common.diagnostics import WARN
from catheter_common.params import Param
from sim_slave.link import Link, LinkConfig

#: the LinkStats counters a side reports, in this order, as `<prefix>_<counter>`
LINK_COUNTERS = ('sent', 'delivered', 'lost_random', 'lost_outage', 'dropped_stale')


def _check_outages(flat):
    LinkConfig.from_flat(0.0, 0.0, 0.0, flat)      # ValueError: odd length, negative length


def link_params(what: str):
    """The simulated link's parameters, declared the same way by every node that holds a side
    of the link (`what` names the traffic this side receives). They apply at run time."""
    return (
        Param('link.delay', 0.2, f'one-way delay of {what}, s', 0.0, 10.0, dynamic=True),
        Param('link.jitter', 0.0, f'extra delay U(0, jitter) per packet of {what}, s', 0.0, 5.0,
              dynamic=True),
        Param('link.loss', 0.0, f'probability that a packet of {what} is lost', 0.0, 1.0,
              dynamic=True),
        Param('link.outages', [4.0, 1.0, 8.0, 1.0], 'link outages as a flat list start,length,'
              '... in s after the first timer tick; [0.0, 0.0] for none', numbers=True,
              dynamic=True, check=_check_outages),
    )


def link_config(values) -> LinkConfig:
    """The LinkConfig of the link.* parameter values."""
    return LinkConfig.from_flat(values['link.delay'], values['link.jitter'],
                                values['link.loss'], values['link.outages'])


def apply_link_changes(changes, values, *links: Link) -> Optional[LinkConfig]:
    """A runtime parameter change (NodeParams `apply`): when it touches link.* parameters,
    their new LinkConfig, set on every one of `links` and returned (ValueError, before any
    link is touched, refuses the change); None when no link parameter changed."""
    if not any(k.startswith('link.') for k in changes):
        return None
    cfg = link_config(values)
    for link in links:
        link.config = cfg
    return cfg


class RunClock:
    """Time of a node's run: seconds since its first timer tick on the node clock.

    `t0` is the node-clock time of the first tick (None before it), `t_last` the run time of
    the latest tick. A tick at an earlier time than the latest (the clock jumped back: a
    bag or simulation restarted) restarts the run at 0 there."""

    def __init__(self) -> None:
        self.t0: Optional[float] = None
        self.t_last: Optional[float] = None

    def tick(self, now: float) -> Tuple[float, bool]:
        """(run time s, restarted) of a timer tick at node-clock time `now` s; restarted is
        True when the clock jumped back (the run time then restarts at 0)."""
        if self.t0 is None:
            self.t0 = now
        t = now - self.t0
        restarted = self.t_last is not None and t < self.t_last
        if restarted:
            self.t0, t = now, 0.0
        self.t_last = t
        return t, restarted

    def at(self, now: float) -> Optional[float]:
        """Run time s of an event between ticks at node-clock time `now`; None before the
        first tick or when the clock jumped back since the latest (the next tick restarts)."""
        if self.t0 is None:
            return None
        t = now - self.t0
        if self.t_last is not None and t < self.t_last:
            return None
        return t


def link_to_diag(diag, links: Sequence[Tuple[str, Link]], t_last: Optional[float], lost: str,
                 counters: Sequence[str] = LINK_COUNTERS) -> None:
    """Each link's `counters` as diagnostics values `<prefix>_<counter>`, and the
    `link_outage` condition (WARN while the first link is in an outage at run time `t_last`,
    saying 'link outage: <lost>')."""
    for prefix, link in links:
        stats = link.stats
        for name in counters:
            diag.set(f'{prefix}_{name}', getattr(stats, name))
    outage = t_last is not None and links[0][1].in_outage(t_last)
    diag.set('link_in_outage', str(outage))
    diag.condition('link_outage', WARN if outage else 0, f'link outage: {lost}')
