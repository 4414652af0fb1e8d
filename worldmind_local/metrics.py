"""Results from episode records: SR and GC with bootstrap CIs, error taxonomy, overheads.

SR = percentage of successful episodes; GC = mean final task_progress x 100 (EmbodiedBench's goal-condition
rate; an episode's GC is its last step's progress). The "Avg" of a table row is the mean over its subsets,
as in the paper's tables. CIs are percentile bootstrap intervals over episodes (fixed RNG seed, so
results.json is reproducible byte for byte).
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
        "SR_ci95": list(bootstrap_ci(success)) if n else None,
        "GC": round(float(np.mean(gc)), 2) if n else None,
        "GC_ci95": list(bootstrap_ci(gc)) if n else None,
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


def summarize_run(streams: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """`streams`: [{"stream_id", "spec": StreamSpec dict, "status", "records": [...]}, ...].

    Returns results.json's body: per-stream metrics and a table per (benchmark, method, planner,
    judge, seed, options) with one column per subset and the average over subsets.
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
        ) + "|" + str(sorted((spec.get("options") or {}).items())) + f"|{spec.get('memory_budget')}"
        row = tables.setdefault(
            row_key,
            {
                "benchmark": spec["benchmark"], "method": spec["method"], "planner": spec["planner"],
                "judge": spec.get("judge") or spec["planner"], "seed": spec.get("seed"),
                "options": spec.get("options"), "memory_budget": spec.get("memory_budget"),
                "subsets": {},
            },
        )
        row["subsets"][spec["subset"]] = {"SR": metrics["SR"], "GC": metrics["GC"], "episodes": metrics["episodes"]}
    for row in tables.values():
        srs = [v["SR"] for v in row["subsets"].values() if v["SR"] is not None]
        gcs = [v["GC"] for v in row["subsets"].values() if v["GC"] is not None]
        row["avg"] = {
            "SR": round(float(np.mean(srs)), 2) if srs else None,
            "GC": round(float(np.mean(gcs)), 2) if gcs else None,
        }
    return {"streams": per_stream, "table": list(tables.values())}
