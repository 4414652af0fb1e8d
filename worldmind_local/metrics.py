"""Results from episode records: SR and GC with intervals fit for each metric, error taxonomy, overheads.

SR = percentage of successful episodes; GC = mean final task_progress x 100 (EmbodiedBench's goal-condition
rate; an episode's GC is its last step's progress). The "Avg" of a table row is the mean over its subsets,
as in the paper's tables.

Intervals (95%, percent; the key names `SR_ci95` / `GC_ci95` are kept from earlier results files):
- `SR_ci95` is Wilson's score interval of the success proportion
  (`scipy.stats.binomtest(k, n).proportion_ci(method="wilson")`): a bootstrap of 0/1 outcomes is
  zero-width at small n and at 0/n or n/n, which says "certain" exactly where the data say least.
- `GC_ci95` is a percentile bootstrap over episodes (`scipy.stats.bootstrap`, fixed seed, so results.json
  is reproducible byte for byte).
`worldmind report` (worldmind_local/reporting/stats.py) uses the same two functions.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

__all__ = ["bootstrap_ci", "stream_metrics", "summarize_run", "TAXONOMY"]

TAXONOMY = ("success", "invalid_action_end", "step_limit", "wrong_termination", "error")
BOOTSTRAP_SAMPLES = 2000
BOOTSTRAP_SEED = 12345


def bootstrap_ci(values: Sequence[float], *, level: float = 0.95) -> tuple[float, float]:
    """Percentile bootstrap CI of the mean, in the units of `values`."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.size == 0:
        return (float("nan"), float("nan"))
    if arr.size == 1 or np.all(arr == arr[0]):
        return (float(arr[0]), float(arr[0])) if arr.size else (float("nan"),) * 2  # type: ignore[return-value]
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    idx = rng.integers(0, arr.size, size=(BOOTSTRAP_SAMPLES, arr.size))
    means = arr[idx].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, 1 - (1 - level) / 2])
    return (round(float(lo), 2), round(float(hi), 2))


def _sr_interval(success: Sequence[float]) -> list[float] | None:
    """Wilson interval (percent) of the successes in `success` (values 0 or 100)."""
    from worldmind_local.reporting.stats import wilson_ci

    ci = wilson_ci(sum(1 for s in success if s), len(success))
    return list(ci) if ci else None


def _gc_interval(gc: Sequence[float]) -> list[float] | None:
    """Percentile bootstrap interval (percent) of the mean GC over episodes."""
    from worldmind_local.reporting.stats import bootstrap_mean_ci

    ci = bootstrap_mean_ci(gc)
    return list(ci) if ci else None


def _num(x: Any) -> float:
    try:
        return float(x or 0)
    except (TypeError, ValueError):
        return 0.0


def _tokens(rec: Mapping[str, Any], role: str) -> float:
    tok = (rec.get("tokens") or {}).get(role) or {}
    if isinstance(tok, Mapping):
        return _num(tok.get("prompt")) + _num(tok.get("completion"))
    return _num(tok)


def _stat(rec: Mapping[str, Any], key: str) -> Any:
    """A method counter: from `method_stats` (current records) or the top level (older records)."""
    stats = rec.get("method_stats") or {}
    return stats.get(key, rec.get(key))


def stream_metrics(records: Iterable[Mapping[str, Any]]) -> dict[str, Any]:
    recs = list(records)
    n = len(recs)
    success = [100.0 * bool(r.get("success")) for r in recs]
    gc = [100.0 * _num(r.get("progress")) for r in recs]
    taxonomy = Counter(str(r.get("taxonomy") or "error") for r in recs)
    reflections = sum(_num(_stat(r, "reflections")) for r in recs)
    distillations = sum(_num(_stat(r, "distillations")) for r in recs)
    retrieval = [float(s) for r in recs for s in (r.get("retrieval_seconds") or [])]
    steps = [_num(r.get("steps")) for r in recs]
    judge_calls = sum(_num(_stat(r, "judge_calls")) for r in recs)
    out: dict[str, Any] = {
        "episodes": n,
        "SR": round(float(np.mean(success)), 2) if n else None,
        "SR_ci95": _sr_interval(success),
        "GC": round(float(np.mean(gc)), 2) if n else None,
        "GC_ci95": _gc_interval(gc),
        "taxonomy": {k: taxonomy.get(k, 0) for k in TAXONOMY} | {
            k: v for k, v in taxonomy.items() if k not in TAXONOMY
        },
        "mean_steps": round(float(np.mean(steps)), 2) if n else None,
        "judge_calls": int(judge_calls),
        "judge_mismatches": int(sum(_num(_stat(r, "judge_mismatches")) for r in recs)),
        "judge_unparseable": int(sum(_num(_stat(r, "judge_unparseable")) for r in recs)),
        "reflections": int(reflections),
        "tokens_per_reflection": round(sum(_tokens(r, "reflector") for r in recs) / reflections, 1)
        if reflections else None,
        "distillations": int(distillations),
        "tokens_per_distillation": round(sum(_tokens(r, "distiller") for r in recs) / distillations, 1)
        if distillations else None,
        "tokens_total": {
            role: int(sum(_tokens(r, role) for r in recs))
            for role in sorted({"planner", *(k for r in recs for k in (r.get("tokens") or {}))})
        },
        "retrieval_ms_per_step": round(1000 * float(np.mean(retrieval)), 4) if retrieval else None,
        "observation": sorted({str(r.get("observation")) for r in recs if r.get("observation")}),
        "calls_per_episode": {
            role: round(n / len(recs), 3) for role, n in sorted(Counter(
                c.get("role") for r in recs for c in (r.get("calls") or [])).items())
        } if recs else {},
        "experience_kept": int(
            sum(1 for r in recs for e in (r.get("experience") or []) if e.get("kept"))
        ),
    }
    return out


def summarize_run(streams: Sequence[Mapping[str, Any]],
                  memory_sources: Mapping[str, Mapping[str, Any]] | None = None) -> dict[str, Any]:
    """`streams`: [{"stream_id", "spec": StreamSpec dict, "status", "records": [...]}, ...].

    Returns results.json's body: per-stream metrics and a table per (benchmark, method, planner,
    judge, seed, options, memory_from) with one column per subset and the average over subsets. A row
    seeded from a memory (`memory_from`: the source's model/benchmark#hash from `memory_sources`) is its
    own row, with its `gain` over the same row run from scratch when the run has that row too.
    """
    per_stream = []
    tables: dict[str, dict[str, Any]] = {}
    for s in streams:
        spec = s["spec"]
        metrics = stream_metrics(s["records"])
        per_stream.append(
            {"stream_id": s["stream_id"], "status": s.get("status"), "error": s.get("error"), **spec,
             "metrics": metrics}
        )
        row_key = "|".join(
            str(spec.get(k)) for k in ("benchmark", "method", "planner", "judge", "seed", "memory_from")
        ) + "|" + str(sorted((spec.get("options") or {}).items())) + f"|{spec.get('memory_budget')}" + \
            f"|{spec.get('perturb')}|{spec.get('task_order_seed')}"
        row = tables.setdefault(
            row_key,
            {
                "benchmark": spec["benchmark"], "method": spec["method"], "planner": spec["planner"],
                "judge": spec.get("judge") or spec["planner"], "seed": spec.get("seed"),
                "options": spec.get("options"), "memory_budget": spec.get("memory_budget"),
                **{k: spec[k] for k in ("perturb", "task_order_seed") if spec.get(k) is not None},
                "subsets": {},
            },
        )
        if spec.get("memory_from"):
            facts = (memory_sources or {}).get(s["stream_id"]) or {}
            row["memory_from"] = facts.get("label") or row.get("memory_from") or spec["memory_from"]
        row["subsets"][spec["subset"]] = {"SR": metrics["SR"], "GC": metrics["GC"], "episodes": metrics["episodes"]}
    for row in tables.values():
        srs = [v["SR"] for v in row["subsets"].values() if v["SR"] is not None]
        gcs = [v["GC"] for v in row["subsets"].values() if v["GC"] is not None]
        row["avg"] = {
            "SR": round(float(np.mean(srs)), 2) if srs else None,
            "GC": round(float(np.mean(gcs)), 2) if gcs else None,
        }
    _gains(tables)
    return {"streams": per_stream, "table": list(tables.values())}


def _gains(tables: Mapping[str, dict[str, Any]]) -> None:
    """`gain` = a seeded row's avg minus the avg of the from-scratch row with the same benchmark,
    method, models, seed, options and budget (the row key with an empty memory_from)."""
    for key, row in tables.items():
        if "memory_from" not in row:
            continue
        parts = key.split("|")
        parts[5] = "None"   # memory_from's place in the row key
        scratch = tables.get("|".join(parts))
        if scratch is None:
            continue
        row["gain"] = {m: (round(row["avg"][m] - scratch["avg"][m], 2)
                           if row["avg"][m] is not None and scratch["avg"][m] is not None else None)
                       for m in ("SR", "GC")}
