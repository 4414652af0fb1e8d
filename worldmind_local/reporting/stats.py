"""Statistics that fit the data, each one a thin call into scipy.

- SR is a proportion of successes: its interval is Wilson's score interval
  (`scipy.stats.binomtest(k, n).proportion_ci(method="wilson")`), which stays honest at small n, at 0/n
  and at n/n (a percentile bootstrap of 0/1 outcomes collapses to a zero-width interval there).
- GC is a mean of per-episode fractions: its interval is a percentile bootstrap over episodes
  (`scipy.stats.bootstrap`). The subset average ("Avg" column) is bootstrapped stratified: episodes are
  resampled within each subset and the statistic is the mean of the subset means, exactly what the
  table reports.
- Two methods on the same episodes are compared paired: exact McNemar for SR (a two-sided binomial
  test on the discordant pairs, `binomtest(b, b + c, 0.5)`), and for GC a paired bootstrap interval of
  the mean difference plus a sign-flip permutation p-value (`scipy.stats.permutation_test`,
  `permutation_type="samples"`).
- Seeds are aggregated as mean +- sample standard deviation (ddof=1) with the number of seeds.

Every resampling uses a fixed seed, so a report is reproducible byte for byte. Values are in percent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

__all__ = [
    "Estimate", "SeedSummary", "PairedComparison", "wilson_ci", "bootstrap_mean_ci", "stratified_mean_ci",
    "sr_estimate", "gc_estimate", "mean_sd", "mcnemar_exact", "paired_comparison",
]

RESAMPLES = 2000
SEED = 12345
LEVEL = 0.95


@dataclass(frozen=True)
class Estimate:
    """A point value with its 95% interval (percent) and the number of episodes behind it."""

    value: float | None
    lo: float | None
    hi: float | None
    n: int
    method: str = ""


@dataclass(frozen=True)
class SeedSummary:
    """Mean +- sd over seeds (sd None for one seed)."""

    mean: float | None
    sd: float | None
    n_seeds: int
    values: tuple[float, ...] = ()


@dataclass(frozen=True)
class PairedComparison:
    """A minus B on the same episodes (percent points) with its interval and p-values."""

    n_pairs: int
    sr_diff: float | None
    sr_ci: tuple[float, float] | None
    sr_p: float | None          # exact McNemar
    discordant: tuple[int, int]  # (A succeeded and B failed, A failed and B succeeded)
    gc_diff: float | None
    gc_ci: tuple[float, float] | None
    gc_p: float | None          # paired sign-flip permutation test


def _round(x: float | None, digits: int = 2) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), digits)


def wilson_ci(successes: int, n: int, level: float = LEVEL) -> tuple[float, float] | None:
    """Wilson score interval of a proportion, in percent; None for n = 0."""
    if n <= 0:
        return None
    ci = stats.binomtest(int(successes), int(n)).proportion_ci(confidence_level=level, method="wilson")
    return (_round(100 * ci.low), _round(100 * ci.high))  # type: ignore[return-value]


def _constant(arrays: Sequence[np.ndarray]) -> bool:
    return all(a.size <= 1 or bool(np.all(a == a[0])) for a in arrays)


def bootstrap_mean_ci(values: Sequence[float], level: float = LEVEL) -> tuple[float, float] | None:
    """Percentile bootstrap interval of the mean over episodes; degenerate samples give a point."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.size == 0:
        return None
    if _constant([arr]):
        return (_round(arr.mean()), _round(arr.mean()))  # type: ignore[return-value]
    res = stats.bootstrap((arr,), np.mean, n_resamples=RESAMPLES, confidence_level=level, method="percentile",
                          rng=np.random.default_rng(SEED))
    return (_round(res.confidence_interval.low), _round(res.confidence_interval.high))  # type: ignore[return-value]


def stratified_mean_ci(groups: Sequence[Sequence[float]], level: float = LEVEL) -> tuple[float, float] | None:
    """Interval of the mean of group means, resampling episodes within each group (the subset average)."""
    arrays = [np.asarray(g, dtype=np.float64) for g in groups if len(g)]
    if not arrays:
        return None
    point = float(np.mean([a.mean() for a in arrays]))
    if _constant(arrays):
        return (_round(point), _round(point))  # type: ignore[return-value]
    if len(arrays) == 1:
        return bootstrap_mean_ci(arrays[0], level)

    def statistic(*samples: np.ndarray, axis: int = -1) -> np.ndarray:
        return np.mean([s.mean(axis=axis) for s in samples], axis=0)

    res = stats.bootstrap(tuple(arrays), statistic, n_resamples=RESAMPLES, confidence_level=level,
                          method="percentile", vectorized=True, rng=np.random.default_rng(SEED))
    return (_round(res.confidence_interval.low), _round(res.confidence_interval.high))  # type: ignore[return-value]


def sr_estimate(successes: Sequence[bool]) -> Estimate:
    n = len(successes)
    k = int(sum(bool(s) for s in successes))
    ci = wilson_ci(k, n)
    return Estimate(_round(100 * k / n) if n else None, ci[0] if ci else None, ci[1] if ci else None, n, "wilson")


def gc_estimate(progress: Sequence[float]) -> Estimate:
    """GC from per-episode progress fractions (0..1)."""
    values = [100.0 * float(p) for p in progress]
    ci = bootstrap_mean_ci(values)
    mean = _round(float(np.mean(values))) if values else None
    return Estimate(mean, ci[0] if ci else None, ci[1] if ci else None, len(values), "bootstrap")


def mean_sd(values: Sequence[float | None]) -> SeedSummary:
    """Mean and sample standard deviation (ddof=1) over seeds; missing values are skipped."""
    vals = [float(v) for v in values if v is not None]
    if not vals:
        return SeedSummary(None, None, 0)
    sd = float(np.std(vals, ddof=1)) if len(vals) > 1 else None
    return SeedSummary(_round(float(np.mean(vals))), _round(sd), len(vals), tuple(vals))


def mcnemar_exact(a: Sequence[bool], b: Sequence[bool]) -> tuple[float, int, int]:
    """Exact McNemar test of paired binary outcomes: (two-sided p, b, c) with b = A-only successes and
    c = B-only successes. Concordant pairs carry no information; with no discordant pair p = 1."""
    if len(a) != len(b):
        raise ValueError(f"paired outcomes need equal lengths, got {len(a)} and {len(b)}")
    only_a = sum(1 for x, y in zip(a, b, strict=True) if x and not y)
    only_b = sum(1 for x, y in zip(a, b, strict=True) if y and not x)
    if only_a + only_b == 0:
        return 1.0, 0, 0
    return float(stats.binomtest(only_a, only_a + only_b, 0.5).pvalue), only_a, only_b


def _paired_diff_ci(a: np.ndarray, b: np.ndarray, level: float) -> tuple[float, float]:
    diff = a - b
    if _constant([diff]):
        return (_round(diff.mean()), _round(diff.mean()))  # type: ignore[return-value]
    res = stats.bootstrap((a, b), lambda x, y, axis=-1: np.mean(x - y, axis=axis), paired=True,
                          vectorized=True, n_resamples=RESAMPLES, confidence_level=level, method="percentile",
                          rng=np.random.default_rng(SEED))
    return (_round(res.confidence_interval.low), _round(res.confidence_interval.high))  # type: ignore[return-value]


def _permutation_p(a: np.ndarray, b: np.ndarray) -> float:
    if np.all(a == b):
        return 1.0
    res = stats.permutation_test((a, b), lambda x, y, axis=-1: np.mean(x - y, axis=axis),
                                 permutation_type="samples", vectorized=True, n_resamples=RESAMPLES,
                                 alternative="two-sided", rng=np.random.default_rng(SEED))
    return float(res.pvalue)


def paired_comparison(success_a: Sequence[bool], success_b: Sequence[bool], gc_a: Sequence[float],
                      gc_b: Sequence[float], level: float = LEVEL) -> PairedComparison:
    """A vs B on the same episodes (aligned lists; GC as fractions 0..1)."""
    n = len(success_a)
    if not n:
        return PairedComparison(0, None, None, None, (0, 0), None, None, None)
    p_sr, only_a, only_b = mcnemar_exact(success_a, success_b)
    sa = 100.0 * np.asarray(success_a, dtype=np.float64)
    sb = 100.0 * np.asarray(success_b, dtype=np.float64)
    ga = 100.0 * np.asarray(gc_a, dtype=np.float64)
    gb = 100.0 * np.asarray(gc_b, dtype=np.float64)
    return PairedComparison(
        n_pairs=n, sr_diff=_round(float((sa - sb).mean())), sr_ci=_paired_diff_ci(sa, sb, level),
        sr_p=_round(p_sr, 4), discordant=(only_a, only_b), gc_diff=_round(float((ga - gb).mean())),
        gc_ci=_paired_diff_ci(ga, gb, level), gc_p=_round(_permutation_p(ga, gb), 4),
    )
