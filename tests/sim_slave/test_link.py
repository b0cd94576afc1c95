"""The UDP-like link: exact delay, loss rate, outages, latest wins, determinism, bad arguments."""
import math

import pytest
from hypothesis import given, settings, strategies as st

from sim_slave import Link, LinkConfig

RATE = 1000.0


def run(link, seconds, rate=RATE):
    """Send i at t = i / rate every period and receive at the same instants.
    Returns [(t_receive, t_sent, payload)] of everything delivered."""
    got = []
    for i in range(int(round(seconds * rate))):
        t = i / rate
        link.send(t, i)
        r = link.receive_stamped(t)
        if r is not None:
            got.append((t, r[0], r[1]))
    return got


def conserved(link):
    s = link.stats
    return s.sent == s.delivered + s.lost_random + s.lost_outage + s.dropped_stale + link.in_flight


@pytest.mark.parametrize('delay', [0.0, 0.001, 0.05, 0.2, 0.5, 1.0])
def test_exact_delay_without_jitter(delay):
    link = Link(LinkConfig(delay=delay, outages=()), seed=0)
    got = run(link, 3.0)
    k = int(round(delay * RATE))
    assert len(got) == 3000 - k
    for t, t_sent, i in got:
        assert t - t_sent == pytest.approx(delay, abs=1e-9)
        assert t_sent == i / RATE
    assert link.stats.dropped_stale == 0 and link.stats.lost_random == 0
    assert conserved(link)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from([0.05, 0.1, 0.3, 0.5]))
def test_loss_rate_within_binomial_bounds(seed, p):
    n = 4000
    link = Link(LinkConfig(delay=0.0, loss=p, outages=()), seed=seed)
    run(link, n / RATE)
    lost = link.stats.lost_random
    sd = math.sqrt(n * p * (1 - p))
    assert abs(lost - n * p) < 5 * sd          # a 5-sigma band: fails ~1 in 3.5 million
    assert link.stats.delivered == n - lost
    assert conserved(link)


def test_outages_deliver_nothing():
    outs = ((4.0, 1.0), (8.0, 1.0))
    link = Link(LinkConfig(delay=0.2, outages=outs), seed=0)
    got = run(link, 12.0)
    sent_times = [ts for _, ts, _ in got]
    assert not any(4.0 <= ts < 5.0 or 8.0 <= ts < 9.0 for ts in sent_times)
    recv_times = [t for t, _, _ in got]
    # nothing arrives for exactly the outage length, one delay later
    assert not any(4.2 + 1e-9 < t < 5.2 - 1e-9 or 8.2 + 1e-9 < t < 9.2 - 1e-9 for t in recv_times)
    assert link.stats.lost_outage == 2000
    assert link.in_outage(4.0) and link.in_outage(4.999) and not link.in_outage(5.0)
    assert not link.in_outage(3.999) and link.in_outage(8.5)
    assert conserved(link)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 1000), st.floats(0.0, 0.3), st.floats(0.0, 0.05), st.floats(0.0, 0.5),
       st.floats(0.0, 2.0), st.floats(0.0, 1.0))
def test_latest_wins_never_out_of_order(seed, delay, jitter, loss, o_start, o_len):
    link = Link(LinkConfig(delay=delay, jitter=jitter, loss=loss, outages=((o_start, o_len),)),
                seed=seed)
    got = run(link, 2.5)
    seq = [i for _, _, i in got]
    # strictly newer every time
    assert all(b > a for a, b in zip(seq[:-1], seq[1:], strict=True))
    for t, t_sent, _ in got:
        assert delay - 1e-9 <= t - t_sent <= delay + jitter + 1e-3 + 1e-9
        assert not (o_start <= t_sent < o_start + o_len)
    assert conserved(link)


def test_jitter_drops_stale_packets_and_counts_them():
    link = Link(LinkConfig(delay=0.1, jitter=0.02, outages=()), seed=5)
    got = run(link, 5.0)
    assert link.stats.dropped_stale > 0
    assert link.stats.delivered == len(got)
    assert conserved(link)


def test_deterministic_for_a_seed_and_independent_of_delay_for_loss():
    cfg = LinkConfig(delay=0.05, jitter=0.01, loss=0.2)
    a = run(Link(cfg, seed=3), 2.0)
    b = run(Link(cfg, seed=3), 2.0)
    c = run(Link(cfg, seed=4), 2.0)
    assert a == b and a != c
    # the same seed loses the same packets whatever the delay (same random draws per send)
    l1 = Link(LinkConfig(delay=0.0, loss=0.3), seed=9)
    l2 = Link(LinkConfig(delay=0.5, jitter=0.1, loss=0.3), seed=9)
    kept1 = [l1.send(i / RATE, i) for i in range(2000)]
    kept2 = [l2.send(i / RATE, i) for i in range(2000)]
    assert kept1 == kept2
    link = Link(cfg, seed=3)
    run(link, 1.0)
    link.reset()
    assert run(link, 2.0) == a


def test_receive_returns_payload_and_none_when_nothing_new():
    link = Link(LinkConfig(delay=0.01), seed=0)
    link.send(0.0, {'x': 1})
    assert link.receive(0.005) is None
    assert link.receive(0.01) == {'x': 1}
    assert link.receive(0.02) is None            # never delivered twice


def test_default_config_is_the_thesis_experiment_two():
    cfg = LinkConfig()
    assert (cfg.delay, cfg.jitter, cfg.loss) == (0.2, 0.0, 0.0)
    assert cfg.outages == ((4.0, 1.0), (8.0, 1.0))
    assert LinkConfig.from_flat() == cfg
    assert LinkConfig(outages=()).outages == ()


def test_from_flat_outages():
    cfg = LinkConfig.from_flat(0.2, 0.0, 0.1, [8.0, 1.0, 4.0, 1.0])
    assert cfg.outages == ((4.0, 1.0), (8.0, 1.0))
    with pytest.raises(ValueError, match='outages'):
        LinkConfig.from_flat(0.2, 0.0, 0.0, [4.0])


@pytest.mark.parametrize('kw,name', [(dict(delay=-0.1), 'delay'), (dict(delay=math.nan), 'delay'),
                                     (dict(jitter=-1e-3), 'jitter'), (dict(loss=1.5), 'loss'),
                                     (dict(loss=-0.1), 'loss'),
                                     (dict(outages=((1.0, -1.0),)), 'outages'),
                                     (dict(outages=((math.inf, 1.0),)), 'outages'),
                                     (dict(outages=(1.0, 2.0)), 'outages')])
def test_bad_config(kw, name):
    with pytest.raises(ValueError, match=name):
        LinkConfig(**kw)


def test_bad_link_arguments():
    with pytest.raises(ValueError, match='config'):
        Link({'delay': 0.1})
    with pytest.raises(ValueError, match='seed'):
        Link(seed=1.5)
    link = Link()
    with pytest.raises(ValueError, match='t'):
        link.send(math.nan, 1)
    link.send(1.0, 1)
    with pytest.raises(ValueError, match='t must not decrease'):
        link.send(0.5, 2)
    with pytest.raises(ValueError, match='t'):
        link.receive(math.inf)
