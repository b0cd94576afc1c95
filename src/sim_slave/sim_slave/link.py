"""A UDP-like one-way link: fixed delay plus jitter, random loss, scripted outages, latest wins.

No retransmission. Each sent packet is either lost (the channel is out at the send time, or
by chance with probability ``loss``) or arrives at ``t_send + delay + U(0, jitter)``. The
receiver keeps only the newest: :meth:`Link.receive` returns the newest-sent packet that
has arrived and is newer than the last one returned; older packets (overtaken because of
jitter) are dropped and counted as stale, never delivered out of order.

Deterministic for a seed: every :meth:`Link.send` draws exactly two random numbers (loss and
jitter) whatever the configuration, so two links with the same seed and different delays see
the same loss pattern.
"""
from __future__ import annotations

import heapq
import random
from dataclasses import asdict, dataclass
from typing import Any, List, Optional, Tuple

from catheter_common.checks import finite, nonneg, probability, seed as check_seed


#: s; a packet due within this of the receive time counts as arrived, so that a delay of
#: exactly k periods is k periods despite floating-point rounding of t + delay.
_ARRIVAL_TOL = 1e-9


@dataclass(frozen=True)
class LinkConfig:
    """Configuration of one direction of the link.

    Attributes:
        delay: s, fixed one-way delay (default 0.2 s, the thesis's added latency).
        jitter: s, extra delay drawn uniformly from [0, jitter] per packet (default 0).
        loss: probability in [0, 1] that a packet is lost at random (default 0).
        outages: ((start, length), ...) in s: packets sent in [start, start + length) are
            lost. Default: the thesis's Experiment II, 1 s at t = 4 s and at t = 8 s. Pass
            ``outages=()`` for a link without outages.
    """

    delay: float = 0.2
    jitter: float = 0.0
    loss: float = 0.0
    outages: Tuple[Tuple[float, float], ...] = ((4.0, 1.0), (8.0, 1.0))

    def __post_init__(self):
        nonneg('delay', self.delay)
        nonneg('jitter', self.jitter)
        probability('loss', self.loss)
        try:
            outs = tuple((float(a), float(b)) for a, b in self.outages)
        except (TypeError, ValueError):
            raise ValueError(f'outages must be a sequence of (start, length) pairs, '
                             f'got {self.outages!r}') from None
        for a, b in outs:
            finite('outages start', a)
            nonneg('outages length', b)
        object.__setattr__(self, 'outages', tuple(sorted(outs)))
        for name in ('delay', 'jitter', 'loss'):
            object.__setattr__(self, name, float(getattr(self, name)))

    @staticmethod
    def from_flat(delay: float = 0.2, jitter: float = 0.0, loss: float = 0.0,
                  outages_flat=(4.0, 1.0, 8.0, 1.0)) -> 'LinkConfig':
        """Build from a flat [start0, length0, start1, length1, ...] list (ROS parameters)."""
        flat = list(outages_flat)
        if len(flat) % 2:
            raise ValueError(f'outages must hold start,length pairs (even length), got {flat!r}')
        return LinkConfig(delay, jitter, loss, tuple(zip(flat[0::2], flat[1::2], strict=True)))

    def describe(self) -> str:
        """One line for logs: 'delay 0.2 s, jitter 0 s, loss 0, outages [(4.0, 1.0), ...]'."""
        return (f'delay {self.delay:g} s, jitter {self.jitter:g} s, loss {self.loss:g}, '
                f'outages {list(self.outages)}')


@dataclass
class LinkStats:
    """Counters of a link. ``sent = delivered + lost_random + lost_outage + dropped_stale
    + in_flight`` at every instant."""
    sent: int = 0
    delivered: int = 0
    lost_random: int = 0
    lost_outage: int = 0
    dropped_stale: int = 0

    def as_dict(self) -> dict:
        return asdict(self)


class Link:
    """One direction of the simulated network.

    Args:
        config: a :class:`LinkConfig` (defaults if None).
        seed: int >= 0 or None (deterministic for a seed).
    """

    def __init__(self, config: Optional[LinkConfig] = None, seed: Optional[int] = 0):
        if config is None:
            config = LinkConfig()
        if not isinstance(config, LinkConfig):
            raise ValueError(f'config must be a LinkConfig, got {type(config).__name__}')
        self.config = config
        self.seed = check_seed('seed', seed)
        self.reset()

    def reset(self) -> None:
        """Empty the channel, zero the counters, restart the random sequence."""
        self._rng = random.Random(self.seed)
        self._heap: List[Tuple[float, int, float, Any]] = []  # (arrival, sequence, sent, payload)
        self._seq = 0
        self._last_seq = -1
        self._t_last_send: Optional[float] = None
        self.stats = LinkStats()

    def in_outage(self, t: float) -> bool:
        """True if the channel is out at time t [s]."""
        for start, length in self.config.outages:
            if start <= t < start + length:
                return True
        return False

    @property
    def in_flight(self) -> int:
        """Packets sent and not yet arrived (or arrived but not yet looked at by receive)."""
        return len(self._heap)

    def send(self, t: float, payload: Any) -> bool:
        """Send `payload` (any object) at time t [s]. Returns False if it was lost."""
        t = finite('t', t)
        if self._t_last_send is not None and t < self._t_last_send:
            raise ValueError(f't must not decrease between sends: {t!r} after '
                             f'{self._t_last_send!r}')
        self._t_last_send = t
        cfg = self.config
        self.stats.sent += 1
        u_loss = self._rng.random()
        u_jit = self._rng.random()
        seq = self._seq
        self._seq += 1
        if self.in_outage(t):
            self.stats.lost_outage += 1
            return False
        if u_loss < cfg.loss:
            self.stats.lost_random += 1
            return False
        heapq.heappush(self._heap, (t + cfg.delay + u_jit * cfg.jitter, seq, t, payload))
        return True

    def receive(self, t: float) -> Optional[Any]:
        """The newest-sent payload that has arrived by time t [s] and is newer than the last one
        returned, or None. Everything older that arrived by t is dropped (counted as stale).
        (A payload that is itself None is indistinguishable: use :meth:`receive_stamped`.)"""
        got = self.receive_stamped(t)
        return None if got is None else got[1]

    def receive_stamped(self, t: float) -> Optional[Tuple[float, Any]]:
        """Like :meth:`receive` but returns (send time in s, payload), or None."""
        t = finite('t', t)
        heap = self._heap
        best = None
        best_seq = self._last_seq
        t_arr = t + _ARRIVAL_TOL
        while heap and heap[0][0] <= t_arr:
            _, seq, t_sent, payload = heapq.heappop(heap)
            if seq > best_seq:
                if best is not None:
                    self.stats.dropped_stale += 1   # overtaken by a newer arrival
                best, best_seq = (t_sent, payload), seq
            else:
                self.stats.dropped_stale += 1
        if best is None:
            return None
        self._last_seq = best_seq
        self.stats.delivered += 1
        return best
