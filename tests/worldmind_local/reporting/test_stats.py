"""Intervals and paired tests against known cases and hand computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from worldmind_local.metrics import stream_metrics
from worldmind_local.reporting.stats import (
    bootstrap_mean_ci,
    mcnemar_exact,
    mean_sd,
    paired_comparison,
    stratified_mean_ci,
    wilson_ci,
)

Z = 1.959963984540054


def _wilson_by_hand(k: int, n: int) -> tuple[float, float]:
    p = k / n
    centre = (p + Z * Z / (2 * n)) / (1 + Z * Z / n)
    half = Z * math.sqrt(p * (1 - p) / n + Z * Z / (4 * n * n)) / (1 + Z * Z / n)
    return 100 * (centre - half), 100 * (centre + half)


@pytest.mark.parametrize("k,n", [(1, 1), (0, 1), (5, 5), (0, 5), (0, 50), (50, 50), (3, 10), (27, 50)])
def test_wilson_matches_the_formula(k: int, n: int) -> None:
    lo, hi = wilson_ci(k, n)
    want = _wilson_by_hand(k, n)
    assert lo == pytest.approx(want[0], abs=0.01) and hi == pytest.approx(want[1], abs=0.01)


def test_wilson_known_cases() -> None:
    assert wilson_ci(1, 1) == (pytest.approx(20.65, abs=0.01), 100.0)       # n = 1: wide, not a point
    assert wilson_ci(0, 1) == (0.0, pytest.approx(79.35, abs=0.01))
    lo, hi = wilson_ci(10, 10)                                               # all success
    assert hi == 100.0 and lo == pytest.approx(100 * 10 / (10 + Z * Z), abs=0.01)
    lo, hi = wilson_ci(0, 10)                                                # all failure
    assert lo == 0.0 and hi == pytest.approx(100 * Z * Z / (10 + Z * Z), abs=0.01)
    assert wilson_ci(0, 0) is None


def test_results_json_sr_interval_is_wilson_and_gc_is_bootstrap() -> None:
    recs = [{"success": True, "progress": 1.0}, {"success": False, "progress": 0.5}]
    m = stream_metrics(recs)
    assert m["SR_ci95"] == list(wilson_ci(1, 2))
    assert m["GC_ci95"] == list(bootstrap_mean_ci([100.0, 50.0]))
    single = stream_metrics([{"success": True, "progress": 1.0}])
    assert single["SR_ci95"][0] < 25 and single["SR_ci95"][1] == 100.0    # no zero-width interval at n = 1


def test_mcnemar_on_a_hand_made_pair() -> None:
    # A succeeds on 6 episodes where B fails, B on 1 where A fails, 5 concordant pairs
    a = [1, 1, 1, 1, 1, 1, 0, 1, 1, 0, 0, 0]
    b = [0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0]
    p, only_a, only_b = mcnemar_exact(a, b)
    assert (only_a, only_b) == (6, 1)
    # exact two-sided binomial on 7 discordant pairs: 2 * P(X <= 1 | n=7, 1/2) = 2 * 8 / 128
    assert p == pytest.approx(2 * (1 + 7) / 2 ** 7)
    assert mcnemar_exact([1, 0], [1, 0])[0] == 1.0
    with pytest.raises(ValueError):
        mcnemar_exact([1], [1, 0])


def test_paired_comparison_difference_interval_and_permutation() -> None:
    sa = [True] * 6 + [False] * 6
    sb = [False] * 6 + [False] * 6
    ga = [1.0] * 6 + [0.2] * 6
    gb = [0.5] * 6 + [0.2] * 6
    cmp = paired_comparison(sa, sb, ga, gb)
    assert cmp.n_pairs == 12 and cmp.sr_diff == 50.0 and cmp.discordant == (6, 0)
    assert cmp.sr_p == pytest.approx(2 * 0.5 ** 6, abs=1e-4)
    assert cmp.gc_diff == 25.0 and cmp.gc_ci[0] <= 25.0 <= cmp.gc_ci[1] and cmp.gc_ci[0] > 0
    assert 0 < cmp.gc_p < 0.05
    same = paired_comparison(sa, sa, ga, ga)
    assert same.sr_diff == 0 and same.sr_ci == (0.0, 0.0) and same.gc_p == 1.0


def test_bootstrap_and_stratified_average() -> None:
    assert bootstrap_mean_ci([40.0]) == (40.0, 40.0) and bootstrap_mean_ci([]) is None
    lo, hi = bootstrap_mean_ci([0, 100, 50, 25, 75])
    assert lo < 50 < hi and (lo, hi) == bootstrap_mean_ci([0, 100, 50, 25, 75])   # fixed seed
    groups = [[0.0, 100.0, 100.0], [50.0, 50.0, 0.0, 100.0]]
    lo, hi = stratified_mean_ci(groups)
    point = np.mean([np.mean(g) for g in groups])
    assert lo <= point <= hi


def test_mean_sd_over_seeds() -> None:
    s = mean_sd([60.0, 68.0, None])
    assert s.mean == 64.0 and s.sd == pytest.approx(math.sqrt(32), abs=0.01) and s.n_seeds == 2
    assert mean_sd([50.0]).sd is None and mean_sd([]).mean is None
