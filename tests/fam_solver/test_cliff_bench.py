"""The cliff bench's follow-up (tests/bench/bench_fam_cliffs.py, issue 15): the paired rounds'
order, the sign-test interval against scipy's binomial distribution and a coverage
simulation, the verdicts, and that a row's verdict follows them (a drop the follow-up confirms
stays "NO"). Fake clocks and given ratios: nothing here is timed."""
import math
import pathlib
import sys

import numpy as np
import pytest
from hypothesis import example, given, strategies as st
from scipy import stats

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / 'bench'))
try:
    import bench_fam_cliffs as bfc
finally:
    sys.path.pop(0)


class FakeClock:
    """A clock the jobs advance by their own cost: CPU times without timing anything."""

    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def fake_jobs(cost_a, cost_b, second_factor=1.0, log=None):
    """Jobs a and b of case i costing cost_a[i] / cost_b[i] on a FakeClock; the second call of
    a back-to-back pair costs second_factor as much (caches warmed by the first)."""
    clock = FakeClock()
    last = {'i': None}

    def make(cost, name):
        def job(i):
            f = second_factor if last['i'] == i else 1.0
            last['i'] = None if last['i'] == i else i
            clock.t += cost[i] * f
            if log is not None:
                log.append((name, i))
        return job
    return make(cost_a, 'a'), make(cost_b, 'b'), clock


def test_paired_times_runs_each_case_at_both_n_back_to_back_in_alternating_order():
    log = []
    n, rounds = 5, 8
    ja, jb, clock = fake_jobs([1.0] * n, [1.0] * n, log=log)
    ta, tb = bfc.paired_times(ja, jb, n, rounds, clock=clock)
    assert ta.shape == tb.shape == (rounds, n)
    body = log[2 * n:]                       # after one warm-up call of each job per case
    assert len(body) == 2 * n * rounds
    a_first = np.zeros(n, dtype=int)
    for p in range(0, len(body), 2):
        (x, i), (y, k) = body[p], body[p + 1]
        assert i == k and {x, y} == {'a', 'b'}           # the pair of one case, back to back
        a_first[i] += x == 'a'
    # every case ran first on each side in half the rounds
    assert np.all(a_first == rounds // 2), a_first
    # the cases rotate: round r starts at case r
    starts = [body[2 * n * r][1] for r in range(rounds)]
    assert starts == [r % n for r in range(rounds)]


def test_paired_ratios_measure_the_cost_ratio_and_cancel_the_second_call_effect():
    """b costs 0.99 of a; the second call of a pair 0.9 of its cost (caches): the per-round
    ratios are 0.99 exactly, with an odd number of cases too (rounds split 5 / 4) -- the median
    over all cases would land between the two orders' 0.891 and 1.1 (8 cases) or on the side of
    the majority order (9), and the (a, b) order every time would give 0.891."""
    for cost_a in ([1.0, 1.3, 0.8, 1.9, 1.1, 1.0, 1.4, 0.9], [1.0, 1.3, 0.8, 1.9, 1.1, 1.0, 1.4,
                                                               0.9, 1.2]):
        cost_b = [0.99 * c for c in cost_a]
        ja, jb, clock = fake_jobs(cost_a, cost_b, second_factor=0.9)
        ta, tb = bfc.paired_times(ja, jb, len(cost_a), 41, clock=clock)
        r = bfc.paired_ratios(ta, tb)
        assert r.shape == (41,)
        assert np.all(np.abs(r - 0.99) < 1e-12), r
        # the median over all cases, per round, is off by 0.5 % (8 cases) or 10 % (9)
        assert np.max(np.abs(np.median(tb / ta, axis=1) - 0.99)) > 0.005
        lo, hi, _ = bfc.sign_interval(r)
        assert bfc.follow_verdict(lo, hi, 0.01) == ('NO', 'confirmed')
        # the same costs: ratios 1, no drop confirmed
        ja, jb, clock = fake_jobs(cost_a, cost_a, second_factor=0.9)
        r = bfc.paired_ratios(*bfc.paired_times(ja, jb, len(cost_a), 41, clock=clock))
        assert np.all(np.abs(r - 1.0) < 1e-12), r
        lo, hi, _ = bfc.sign_interval(r)
        assert bfc.follow_verdict(lo, hi, 0.01)[0] in ('yes', 'within noise')   # 1 to rounding


def test_paired_times_rejects_too_few_cases_or_rounds():
    ja, jb, clock = fake_jobs([1.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match='n_jobs'):
        bfc.paired_times(ja, jb, 1, 5, clock=clock)
    with pytest.raises(ValueError, match='rounds'):
        bfc.paired_times(ja, jb, 2, 0, clock=clock)


def _l_reference(n, conf):
    """The sign-test interval's order-statistic index from scipy's binomial cdf."""
    alpha = 0.5 * (1.0 - conf)
    ls = [l_ for l_ in range(1, n + 1) if stats.binom.cdf(l_ - 1, n, 0.5) <= alpha]
    return max(ls) if ls else 0


@pytest.mark.parametrize('conf', [0.8, 0.9, 0.95, 0.99])
def test_sign_interval_order_statistics_agree_with_scipy_binomial(conf):
    for n in list(range(1, 60)) + [61, 81, 101, 160, 243]:
        x = np.arange(n, dtype=float)[::-1] * 0.5       # distinct: the index is the value
        lo, hi, cov = bfc.sign_interval(x, conf)
        l_ = _l_reference(n, conf)
        if l_ == 0:
            assert (lo, hi, cov) == (-math.inf, math.inf, 1.0), n
            continue
        assert lo == 0.5 * (l_ - 1) and hi == 0.5 * (n - l_), (n, l_, lo, hi)
        assert cov == pytest.approx(1.0 - 2.0 * stats.binom.cdf(l_ - 1, n, 0.5), abs=1e-12)
        assert cov >= conf


def test_sign_interval_covers_the_median_as_often_as_promised():
    """4000 samples of 81 log-normal ratios around a known median (deterministic seed): the
    95 % interval holds it in 95.5 % of them (its exact coverage at n = 81), not far less or
    more (an interval too narrow would confirm noise as drops)."""
    rng = np.random.default_rng(81)
    x = 0.995 * np.exp(0.01 * rng.standard_normal((4000, 81)))
    hits = 0
    for s in x:
        lo, hi, cov = bfc.sign_interval(s)
        hits += lo <= 0.995 <= hi
    assert cov == pytest.approx(0.9552, abs=1e-4)
    assert 0.94 <= hits / 4000 <= 0.97, hits


@given(st.lists(st.floats(0.5, 2.0, allow_nan=False), min_size=1, max_size=200),
       st.sampled_from([0.9, 0.95, 0.99]))
@example([1.0, 1.0, 1.0, 1.0, 1.0, 1.0], 0.95)
@example([0.9, 1.1, 1.0, 0.95, 1.05, 1.0, 0.99], 0.99)
def test_sign_interval_holds_the_sample_median_and_widens_with_confidence(x, conf):
    lo, hi, cov = bfc.sign_interval(x, conf)
    med = float(np.median(x))
    assert lo <= med <= hi
    assert cov >= conf
    assert (lo == -math.inf or lo in x) and (hi == math.inf or hi in x)
    lo2, hi2, _ = bfc.sign_interval(x, 0.5 * (1.0 + conf))
    assert lo2 <= lo and hi2 >= hi


@pytest.mark.parametrize('x, conf, match', [([], 0.95, 'non-empty'),
                                            ([1.0, float('nan')], 0.95, 'finite'),
                                            ([1.0, 2.0], 1.0, 'conf'),
                                            ([1.0, 2.0], 0.0, 'conf')])
def test_sign_interval_rejects_bad_input(x, conf, match):
    with pytest.raises(ValueError, match=match):
        bfc.sign_interval(x, conf)


@pytest.mark.parametrize('lo, hi, drop, expected', [
    (0.985, 0.998, 0.010, ('NO', 'confirmed')),
    (0.985, 0.99999, 0.002, ('NO', 'confirmed')),
    (1.000, 1.010, 0.010, ('yes', 'no drop')),
    (1.002, 1.010, 0.030, ('yes', 'no drop')),
    (0.995, 1.005, 0.010, ('within noise', 'within noise')),
    (0.985, 1.005, 0.010, ('NO', 'inconclusive')),
    (0.990, 1.005, 0.010, ('NO', 'inconclusive')),     # cannot exclude the coarse drop itself
    (0.9901, 1.0, 0.010, ('within noise', 'within noise')),
])
def test_follow_verdict(lo, hi, drop, expected):
    assert bfc.follow_verdict(lo, hi, drop) == expected


def test_median_drops_lists_every_drop_from_the_largest_median_before():
    ns = [1, 2, 4, 8, 12]
    meds = [1.0, 2.0, 1.9, 2.1, 2.05]
    noise = {1: 0.0, 2: 0.01, 4: 0.02, 8: 0.03, 12: 0.04}
    d = bfc.median_drops(meds, noise, ns)
    assert [(k, j) for k, j, _, _ in d] == [(1, 2), (3, 4)]
    assert d[0][2] == pytest.approx(0.05) and d[0][3] == pytest.approx(0.03)
    assert d[1][2] == pytest.approx(1.0 - 2.05 / 2.1) and d[1][3] == pytest.approx(0.07)
    assert bfc.median_drops([1.0, 1.0, 1.5], noise, [1, 2, 4]) == []
    # from the largest median before, not the previous one: 2.0 -> 1.9 -> 1.95 drops twice
    d = bfc.median_drops([1.0, 2.0, 1.9, 1.95], noise, [1, 2, 4, 8])
    assert [(k, j) for k, j, _, _ in d] == [(1, 2), (1, 3)]
    assert d[1][2] == pytest.approx(0.025) and d[1][3] == pytest.approx(0.04)


NS = [12, 48, 64, 80, 81, 100]


def _row(meds, noise):
    """A row's per-case times: three cases per N with the given median."""
    times = {n: np.array([0.9, 1.0, 1.2]) * m for n, m in zip(NS, meds, strict=True)}
    return times, dict(zip(NS, noise, strict=True))


@pytest.mark.parametrize('ratios, verdict, what', [
    (np.full(61, 0.990), 'NO', 'confirmed'),
    (np.full(61, 1.004), 'yes', 'no drop'),
    (1.0 + 0.001 * np.sin(np.arange(61)), 'within noise', 'within noise'),
    (1.0 + 0.05 * np.sin(np.arange(61)), 'NO', 'inconclusive'),
])
def test_cliff_report_follows_up_a_drop_beyond_the_noise(ratios, verdict, what, capsys):
    """N = 80 -> 81 drops 1.0 % against a noise of 0.4 %: only that pair is followed up, the
    row keeps its coarse figures, and its verdict is the follow-up's (confirmed: "NO")."""
    times, noise = _row([0.2, 0.3, 0.35, 0.4, 0.396, 0.45], [0.001, 0.001, 0.001, 0.002, 0.002,
                                                            0.001])
    calls = []

    def follow(na, nb):
        calls.append((na, nb))
        return ratios
    ok, drop, v, coarse, lines = bfc.cliff_report('row', times, noise, NS, ['c0', 'c1', 'c2'],
                                                  0.2, follow)
    out = capsys.readouterr().out
    assert calls == [(80, 81)]
    assert ok and drop == pytest.approx(0.01)
    assert coarse == 'NO' and v == verdict
    assert len(lines) == 1 and 'N = 80 -> 81' in lines[0] and lines[0].endswith(verdict)
    assert what in lines[0]
    assert f'| {verdict} (coarse NO; follow-up: N = 80 -> 81 1.0 % {what})' in out
    assert 'largest drop 1.0 % (N = 80 -> 81), noise 0.4 %' in out


def test_cliff_report_a_smaller_drop_beyond_its_noise_is_not_hidden_by_a_larger_one(capsys):
    """The largest drop (N = 64 -> 80, 3 %) is within its noise (5 %), a smaller one (80 -> 81,
    1 %) is not: the row is "NO" (the coarse check used to read only the largest drop); no
    follow-up given, so it stays "NO"; drops within noise are not followed up."""
    times, noise = _row([0.2, 0.3, 0.4, 0.388, 0.384, 0.45], [0.001, 0.001, 0.025, 0.025,
                                                             0.001, 0.001])
    ok, drop, v, coarse, lines = bfc.cliff_report('row', times, noise, NS, ['c0', 'c1', 'c2'],
                                                  0.2, None)
    assert drop == pytest.approx(0.04) and v == coarse == 'NO' and lines == []
    times, noise = _row([0.2, 0.3, 0.4, 0.388, 0.39, 0.45], [0.001, 0.001, 0.025, 0.025,
                                                            0.001, 0.001])
    calls = []
    ok, drop, v, coarse, lines = bfc.cliff_report('row', times, noise, NS, ['c0', 'c1', 'c2'],
                                                  0.2, lambda a, b: calls.append((a, b)))
    assert v == coarse == 'within noise' and calls == [] and lines == []
    capsys.readouterr()


def test_cliff_summary_counts_the_rows_after_their_follow_ups(capsys):
    rows = [(True, 0.0, 'yes', 'yes', []), (True, 0.01, 'NO', 'NO', ['follow-up x']),
            (True, 0.02, 'within noise', 'NO', ['follow-up y']),
            (True, 0.005, 'within noise', 'within noise', [])]
    bfc.cliff_summary(rows)
    out = capsys.readouterr().out
    assert out.splitlines()[:2] == ['follow-up x', 'follow-up y']
    assert ('medians non-decreasing: 1 rows yes, 2 within noise, 1 no; largest drop 2.0 %; '
            'coarse "NO" 2 rows, followed up: 1 stay "NO"') in out
