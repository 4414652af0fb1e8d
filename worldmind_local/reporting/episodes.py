"""Per-episode quantities every table and figure reads, computed in one place from episode records."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from worldmind_local.reporting.load import Stream
from worldmind_local.reporting.stats import Estimate, gc_estimate, sr_estimate, stratified_mean_ci

__all__ = ["successes", "progress", "sr", "gc", "avg_over_subsets", "pooled_avg", "taxonomy",
           "overhead", "TAXONOMY", "pairs"]

TAXONOMY = ("success", "invalid_action_end", "step_limit", "wrong_termination", "error")


def _num(x: Any) -> float:
    try:
        return float(x or 0)
    except (TypeError, ValueError):
        return 0.0


def successes(records: Iterable[dict[str, Any]]) -> list[bool]:
    return [bool(r.get("success")) for r in records]


def progress(records: Iterable[dict[str, Any]]) -> list[float]:
    return [_num(r.get("progress")) for r in records]


def sr(records: Sequence[dict[str, Any]]) -> Estimate:
    return sr_estimate(successes(records))


def gc(records: Sequence[dict[str, Any]]) -> Estimate:
    return gc_estimate(progress(records))


def avg_over_subsets(streams: Sequence[Stream], metric: str) -> float | None:
    """The paper's "Avg": the mean over subsets of each subset's SR or GC (percent)."""
    values = [(sr if metric == "SR" else gc)(s.records).value for s in streams if s.records]
    values = [v for v in values if v is not None]
    return round(float(np.mean(values)), 2) if values else None


def pooled_avg(streams: Sequence[Stream], metric: str) -> Estimate:
    """The average over subsets with a stratified bootstrap interval (episodes resampled per subset).
    Streams of the same subset (several seeds) are pooled into that subset's sample."""
    by_subset: dict[str, list[float]] = {}
    for s in streams:
        vals = (100.0 * np.asarray(successes(s.records), dtype=float) if metric == "SR"
                else 100.0 * np.asarray(progress(s.records), dtype=float))
        by_subset.setdefault(str(s.spec.get("subset")), []).extend(vals.tolist())
    groups = [v for v in by_subset.values() if v]
    if not groups:
        return Estimate(None, None, None, 0)
    point = round(float(np.mean([np.mean(g) for g in groups])), 2)
    ci = stratified_mean_ci(groups)
    return Estimate(point, ci[0] if ci else None, ci[1] if ci else None, sum(len(g) for g in groups),
                    "stratified bootstrap")


def taxonomy(records: Iterable[dict[str, Any]]) -> Counter[str]:
    return Counter(str(r.get("taxonomy") or "error") for r in records)


def _stat(rec: dict[str, Any], key: str) -> float:
    stats = rec.get("method_stats") or {}
    return _num(stats.get(key, rec.get(key)))


def _tokens(rec: dict[str, Any], role: str) -> float:
    tok = (rec.get("tokens") or {}).get(role) or {}
    if isinstance(tok, dict):
        return _num(tok.get("prompt")) + _num(tok.get("completion"))
    return _num(tok)


def overhead(records: Sequence[dict[str, Any]]) -> dict[str, float | None]:
    """The paper's practical-overhead quantities for a set of episodes.

    tokens per reflection / distillation: reflector / distiller tokens over the number of reflections /
    distillations; retrieval seconds per step: total retrieval time over env steps (the time retrieval
    adds to each step, as the paper reports it); calls and tokens per episode: every model call and token.
    """
    n = len(records)
    reflections = sum(_stat(r, "reflections") for r in records)
    distillations = sum(_stat(r, "distillations") for r in records)
    steps = sum(_num(r.get("steps")) for r in records)
    retrieval = sum(_num(x) for r in records for x in (r.get("retrieval_seconds") or []))
    calls = sum(len(r.get("calls") or []) for r in records)
    tokens = sum(_tokens(r, role) for r in records for role in (r.get("tokens") or {}))
    return {
        "tokens_per_reflection": round(sum(_tokens(r, "reflector") for r in records) / reflections, 1)
        if reflections else None,
        "tokens_per_distillation": round(sum(_tokens(r, "distiller") for r in records) / distillations, 1)
        if distillations else None,
        "retrieval_s_per_step": round(retrieval / steps, 6) if steps and any(
            r.get("retrieval_seconds") for r in records) else None,
        "calls_per_episode": round(calls / n, 2) if n else None,
        "tokens_per_episode": round(tokens / n, 1) if n else None,
    }


def pairs(a: Sequence[Stream], b: Sequence[Stream], *, match_seed: bool = True
          ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Episodes both sides ran, aligned: keyed by (seed, subset, task id); a side's seeds are matched to
    the other's when `match_seed`, else every episode is keyed by (subset, task id) only."""
    def index(streams: Sequence[Stream]) -> dict[tuple[Any, ...], dict[str, Any]]:
        out = {}
        for s in streams:
            for r in s.records:
                key = (s.spec.get("seed") if match_seed else None, s.spec.get("subset"), r.get("task_id"),
                       r.get("index"))
                out.setdefault(key, r)
        return out

    ia, ib = index(a), index(b)
    keys = sorted(set(ia) & set(ib), key=str)
    return [ia[k] for k in keys], [ib[k] for k in keys]
