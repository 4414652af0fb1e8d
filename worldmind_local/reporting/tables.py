"""The paper's tables from streams: main results, ablations, memory budget, taxonomy, overhead, per stream.

Every builder takes the loaded streams and returns `Table`s (none when the streams hold nothing for it).
Seeds are aggregated as mean +- sd with the number of seeds shown; the "Avg" column is the mean over
subsets, computed per seed and then aggregated, exactly as a paper table row. The robustness, transfer
and paired-comparison tables live in `tables_paired.py`.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

import worldmind_local.reporting.episodes as ep
from worldmind_local.reporting.load import Stream
from worldmind_local.reporting.model import (
    Num,
    Table,
    caption_facts,
    is_clean,
    seed_summary,
    short_model,
    short_subset,
    subset_order,
)

__all__ = ["main_tables", "ablation_table", "controlled_ablation_table", "memory_budget_tables",
           "taxonomy_table", "overhead_table", "stream_table", "group_by", "subset_columns", "STAT_NOTE",
           "EPISODIC_METHODS", "row_cells"]

EPISODIC_METHODS = {"react", "bon", "simura", "worldmind_baseline"}
STAT_NOTE = ("Cells: mean over seeds ± sample sd (ddof=1) when there are several seeds; Avg = mean over "
             "subsets, per seed. Intervals in the per-stream table: Wilson 95% for SR, percentile "
             "bootstrap over episodes for GC.")


def group_by(streams: Sequence[Stream], key: Callable[[Stream], Any]) -> dict[Any, list[Stream]]:
    out: dict[Any, list[Stream]] = defaultdict(list)
    for s in streams:
        out[key(s)].append(s)
    return dict(out)


def subset_columns(benchmark: str, streams: Sequence[Stream]) -> list[str]:
    return subset_order(benchmark, {str(s.spec.get("subset")) for s in streams})


def _per_seed(streams: Sequence[Stream], metric: str, subset: str | None) -> dict[Any, float | None]:
    """seed -> the metric of that seed's stream of `subset` (None = the average over its subsets)."""
    by_seed = group_by(streams, lambda s: s.spec.get("seed"))
    out: dict[Any, float | None] = {}
    for seed, group in by_seed.items():
        if subset is None:
            out[seed] = ep.avg_over_subsets(group, metric)
        else:
            match = [s for s in group if s.spec.get("subset") == subset and s.records]
            if match:
                out[seed] = (ep.sr if metric == "SR" else ep.gc)(match[0].records).value
    return out


def row_cells(streams: Sequence[Stream], subsets: Sequence[str]) -> list[Num]:
    """SR Avg, SR per subset, GC Avg, GC per subset: each mean ± sd over seeds."""
    cells = []
    for metric in ("SR", "GC"):
        cells.append(seed_summary(_per_seed(streams, metric, None)))
        cells += [seed_summary(_per_seed(streams, metric, sub)) for sub in subsets]
    return cells


def _metric_header(subsets: Sequence[str]) -> tuple[list[str], list[tuple[str, int]]]:
    cols = [f"{m} {x}" for m in ("SR", "GC") for x in ["Avg", *(short_subset(s) for s in subsets)]]
    return cols, [("Success Rate (SR %)", len(subsets) + 1), ("Goal Condition (GC %)", len(subsets) + 1)]


def _n_seeds(streams: Sequence[Stream]) -> int:
    return len({s.spec.get("seed") for s in streams})


def main_tables(streams: Sequence[Stream]) -> list[Table]:
    """One table per benchmark in the paper's layout: Backbone | Method | Memory Scope | SR | GC."""
    tables = []
    clean = [s for s in streams if is_clean(s)]
    for bench, group in sorted(group_by(clean, lambda s: s.spec.get("benchmark")).items()):
        subsets = subset_columns(bench, group)
        metric_cols, groups = _metric_header(subsets)
        rows = []
        keyed = group_by(group, lambda s: (short_model(s.spec.get("planner")), short_model(s.judge), s.label))
        for (planner, judge, label), members in sorted(keyed.items()):
            scope = "Episodic" if members[0].spec.get("method") in EPISODIC_METHODS else "Global"
            backbone = planner if judge == planner else f"{planner} (judge {judge})"
            rows.append([backbone, label, scope, *row_cells(members, subsets), _n_seeds(members),
                         sum(len(s.records) for s in members)])
        tables.append(Table(
            key=f"main_{bench}", title=f"Main results on {bench}",
            columns=["Backbone", "Method", "Memory Scope", *metric_cols, "Seeds", "Episodes"], rows=rows,
            header_groups=[("", 3), *groups, ("", 2)],
            caption=f"Main results on {bench} (SR and GC per subset and their average). " + caption_facts(group),
            notes=[STAT_NOTE],
        ))
    return tables


ABLATION = (("worldmind_baseline", "-", "-"), ("worldmind_goal_only", "✓", "-"),
            ("worldmind_process_only", "-", "✓"), ("worldmind", "✓", "✓"))


def ablation_table(streams: Sequence[Stream]) -> Table | None:
    """Goal / Process / Full / Baseline: SR and GC (averages over subsets) per benchmark."""
    names = {m for m, _, _ in ABLATION}
    pool = [s for s in streams if is_clean(s) and s.spec.get("method") in names and not s.spec.get("options")]
    if len({s.spec.get("method") for s in pool}) < 2:
        return None
    benches = sorted({s.spec.get("benchmark") for s in pool})
    rows = []
    for planner, group in sorted(group_by(pool, lambda s: short_model(s.spec.get("planner"))).items()):
        for method, goal, process in ABLATION:
            row: list[Any] = [planner, goal, process]
            members = [s for s in group if s.spec.get("method") == method]
            if not members:
                continue
            for bench in benches:
                sub = [s for s in members if s.spec.get("benchmark") == bench]
                row += [seed_summary(_per_seed(sub, "SR", None)), seed_summary(_per_seed(sub, "GC", None))]
            row.append(_n_seeds(members))
            rows.append(row)
    cols = ["Backbone", "Goal", "Process"] + [f"{b} {m}" for b in benches for m in ("SR", "GC")] + ["Seeds"]
    return Table("ablation", "Ablation: Goal and Process Experience", cols, rows,
                 header_groups=[("", 1), ("Components", 2), *((b, 2) for b in benches), ("", 1)],
                 caption="Ablation of Goal Guidance and Process Supervision (worldmind_baseline, "
                         "worldmind_goal_only, worldmind_process_only, worldmind); SR and GC are averages "
                         "over the subsets run. " + caption_facts(pool), notes=[STAT_NOTE])


CONTROLLED = (("Baseline", "worldmind_baseline", "--", "--", "--", "none"),
              ("NaiveMem (control)", "naivemem", "--", "raw", "--", "raw trajectory"),
              ("WM w/o Verifier", "worldmind_no_verifier", "✓", "distilled", "--", "both"),
              ("WM w/o Goal", "worldmind_process_only", "✓", "--", "✓", "rules only"),
              ("WorldMind (Full)", "worldmind", "✓", "distilled", "✓", "both"))


def controlled_ablation_table(streams: Sequence[Stream]) -> Table | None:
    """The controlled memory ablation: mean GC (and SR) over the subsets run, per variant."""
    names = {m for _, m, *_ in CONTROLLED}
    pool = [s for s in streams if is_clean(s) and s.spec.get("method") in names and not s.spec.get("options")]
    if not {"naivemem", "worldmind_no_verifier"} & {s.spec.get("method") for s in pool}:
        return None
    rows = []
    for (bench, planner), group in sorted(group_by(
            pool, lambda s: (s.spec.get("benchmark"), short_model(s.spec.get("planner")))).items()):
        n_sub = len({s.spec.get("subset") for s in group})
        for variant, method, process, goal, verifier, fmt in CONTROLLED:
            members = [s for s in group if s.spec.get("method") == method]
            if members:
                rows.append([bench, planner, variant, process, goal, verifier, fmt,
                             seed_summary(_per_seed(members, "GC", None)),
                             seed_summary(_per_seed(members, "SR", None)), _n_seeds(members), n_sub])
    cols = ["Benchmark", "Backbone", "Variant", "Process Exp.", "Goal Exp.", "Verifier", "Memory Format",
            "Mean GC", "Mean SR", "Seeds", "Subsets"]
    return Table("controlled_ablation", "Controlled memory ablation", cols, rows,
                 caption="Controlled memory ablation: the same harness, retrieval and prompt skeleton; only "
                         "the memory and verification components differ. Mean over the subsets run. "
                         + caption_facts(pool), notes=[STAT_NOTE])


def _top_k(s: Stream) -> int | None:
    k = (s.spec.get("options") or {}).get("top_k")
    if k is not None:
        return int(k)
    try:
        from worldmind_local.registry import BENCHMARKS

        return int(BENCHMARKS.get(s.spec.get("benchmark")).default_top_k)
    except Exception:
        return None


def _budget_pool(streams: Sequence[Stream]) -> list[Stream]:
    """Streams of a budget/top-k sweep: no seed memory, perturbation or permutation, and a group
    (benchmark, planner, method) in which some stream sets a budget or a top_k."""
    pool = [s for s in streams if not any(s.spec.get(k) is not None
                                          for k in ("memory_from", "perturb", "task_order_seed"))]
    swept = {(s.spec.get("benchmark"), s.spec.get("planner"), s.spec.get("method")) for s in pool
             if s.spec.get("memory_budget") is not None or "top_k" in (s.spec.get("options") or {})}
    return [s for s in pool if (s.spec.get("benchmark"), s.spec.get("planner"), s.spec.get("method")) in swept
            and set(s.spec.get("options") or {}) <= {"top_k"}]


def budget_label(budget: int | None, k: int | None) -> str:
    return f"Mem{'∞' if budget is None else budget} (top-{k if k is not None else '?'})"


def memory_budget_tables(streams: Sequence[Stream]) -> list[Table]:
    """MemN (top-k) rows: SR and GC per subset and average, per (benchmark, planner, method)."""
    tables = []
    pool = _budget_pool(streams)
    for (bench, planner, method), group in sorted(group_by(
            pool, lambda s: (s.spec.get("benchmark"), s.spec.get("planner"), s.spec.get("method"))).items()):
        subsets = subset_columns(bench, group)
        metric_cols, groups = _metric_header(subsets)
        rows = []
        keyed = group_by(group, lambda s: (_top_k(s) or 0, s.spec.get("memory_budget")))
        for (k, budget), members in sorted(keyed.items(), key=lambda kv: (kv[0][0], kv[0][1] is None,
                                                                          kv[0][1] or 0)):
            rows.append([budget_label(budget, k or None), budget if budget is not None else "",
                         k or "", *row_cells(members, subsets), _n_seeds(members)])
        tables.append(Table(
            key=f"memory_budget_{bench}_{short_model(planner)}_{method}".replace("/", "_"),
            title=f"Memory budget and top-k on {bench} ({method}, {short_model(planner)})",
            columns=["Memory Setting", "Budget", "top-k", *metric_cols, "Seeds"], rows=rows,
            header_groups=[("", 3), *groups, ("", 1)],
            caption="Memory budget sweep: MemN caps the repository at N experiences (Mem0 = no memory, "
                    "Mem∞ = unbounded); top-k is the retrieval size. " + caption_facts(group),
            notes=[STAT_NOTE]))
    return tables


TAXONOMY_HEAD = {"success": "Success", "invalid_action_end": "Invalid-action end", "step_limit": "Step limit",
                 "wrong_termination": "Wrong termination", "error": "Error"}


def taxonomy_table(streams: Sequence[Stream]) -> Table | None:
    """Episodes per end category (the paper's error analysis), per method, summed over subsets and seeds."""
    pool = [s for s in streams if is_clean(s) and s.records]
    if not pool:
        return None
    rows = []
    for (bench, planner, label), members in sorted(group_by(
            pool, lambda s: (s.spec.get("benchmark"), short_model(s.spec.get("planner")), s.label)).items()):
        counts = ep.taxonomy(r for s in members for r in s.records)
        total = sum(counts.values())
        rows.append([bench, planner, label, *(counts.get(k, 0) for k in ep.TAXONOMY), total,
                     Num(round(100 * (total - counts.get("success", 0)) / total, 1) if total else None)])
    cols = ["Benchmark", "Backbone", "Method", *(TAXONOMY_HEAD[k] for k in ep.TAXONOMY), "Episodes",
            "Failure %"]
    return Table("taxonomy", "Error taxonomy", cols, rows,
                 caption="Error analysis: how episodes ended (invalid-action limit, step limit, wrong "
                         "termination), summed over subsets and seeds. " + caption_facts(pool))


OVERHEAD_ROWS = (("tokens_per_reflection", "Process Exp. (tokens/reflection)"),
                 ("tokens_per_distillation", "Goal Exp. (tokens/distillation)"),
                 ("retrieval_s_per_step", "Retrieval time (seconds/step)"),
                 ("calls_per_episode", "Model calls per episode"),
                 ("tokens_per_episode", "Tokens per episode"))


def overhead_table(streams: Sequence[Stream]) -> Table | None:
    """Practical overhead per method: each metric per subset and its average over subsets."""
    pool = [s for s in streams if is_clean(s) and s.records]
    if not pool:
        return None
    subsets = subset_order(pool[0].spec.get("benchmark"), {str(s.spec.get("subset")) for s in pool})
    rows = []
    for (bench, planner, label), members in sorted(group_by(
            pool, lambda s: (s.spec.get("benchmark"), short_model(s.spec.get("planner")), s.label)).items()):
        per_subset = {sub: ep.overhead([r for s in members if s.spec.get("subset") == sub for r in s.records])
                      for sub in subsets}
        for key, name in OVERHEAD_ROWS:
            values = [per_subset[sub][key] for sub in subsets]
            present = [v for v in values if v is not None]
            digits = 4 if key == "retrieval_s_per_step" else 1
            avg = round(sum(present) / len(present), 6) if present else None
            rows.append([bench, planner, label, name, *(Num(v, digits=digits) for v in values),
                         Num(avg, digits=digits)])
    cols = ["Benchmark", "Backbone", "Method", "Metric", *(short_subset(s) for s in subsets), "Average"]
    return Table("overhead", "Practical overhead", cols, rows,
                 caption="Practical overhead: tokens per reflection (Process Experience) and per "
                         "distillation (Goal Experience), retrieval seconds per env step, model calls and "
                         "tokens per episode; Average = mean over subsets. " + caption_facts(pool))


def stream_table(streams: Sequence[Stream]) -> Table:
    """Every stream with its own intervals: SR with Wilson, GC with a bootstrap over episodes."""
    rows = []
    for s in sorted(streams, key=lambda s: (s.run, s.stream_id)):
        sr, gc = ep.sr(s.records), ep.gc(s.records)
        rows.append([s.run, s.stream_id, s.spec.get("benchmark"), s.spec.get("subset"), s.label,
                     short_model(s.spec.get("planner")), s.spec.get("seed"), s.spec.get("perturb") or "",
                     "" if s.spec.get("task_order_seed") is None else s.spec.get("task_order_seed"),
                     "" if s.spec.get("memory_budget") is None else s.spec.get("memory_budget"),
                     "yes" if s.spec.get("memory_from") else "", len(s.records),
                     Num(sr.value, lo=sr.lo, hi=sr.hi), Num(gc.value, lo=gc.lo, hi=gc.hi), s.status or ""])
    cols = ["Run", "Stream", "Benchmark", "Subset", "Method", "Planner", "Seed", "Perturb", "Task order",
            "Budget", "Seed memory", "Episodes", "SR [Wilson 95%]", "GC [bootstrap 95%]", "Status"]
    return Table("streams", "Per-stream results with intervals", cols, rows,
                 caption="Every stream: SR with its Wilson 95% interval, GC with a percentile bootstrap 95% "
                         "interval over episodes. " + caption_facts(streams))
