"""Tables that compare streams on the same episodes: method comparisons, robustness, transfer, task order.

Two streams that ran the same tasks are compared episode by episode (`episodes.pairs`): exact McNemar for
SR, a paired bootstrap interval and a sign-flip permutation p-value for GC (`stats.paired_comparison`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import worldmind_local.reporting.episodes as ep
from worldmind_local.reporting.load import Stream
from worldmind_local.reporting.model import Num, Table, caption_facts, is_clean, seed_summary, short_model
from worldmind_local.reporting.stats import mean_sd, paired_comparison
from worldmind_local.reporting.tables import group_by

__all__ = ["comparison_table", "robustness_table", "task_order_table", "transfer_table", "transfer_matrix",
           "source_label", "twin_of"]

PAIRED_NOTE = ("Δ = first minus second on the same episodes (paired by seed, subset and task), in percent "
               "points, with a paired bootstrap 95% interval; SR p: exact McNemar on the discordant pairs; "
               "GC p: paired sign-flip permutation test.")


def _diff_cells(a: Sequence[Stream], b: Sequence[Stream], *, match_seed: bool = True) -> list[Any]:
    ra, rb = ep.pairs(a, b, match_seed=match_seed)
    cmp = paired_comparison(ep.successes(ra), ep.successes(rb), ep.progress(ra), ep.progress(rb))
    sr = Num(cmp.sr_diff, lo=cmp.sr_ci[0] if cmp.sr_ci else None, hi=cmp.sr_ci[1] if cmp.sr_ci else None)
    gc = Num(cmp.gc_diff, lo=cmp.gc_ci[0] if cmp.gc_ci else None, hi=cmp.gc_ci[1] if cmp.gc_ci else None)
    return [cmp.n_pairs, sr, Num(cmp.sr_p, digits=3), f"{cmp.discordant[0]}/{cmp.discordant[1]}", gc,
            Num(cmp.gc_p, digits=3)]


DIFF_COLS = ["Pairs", "ΔSR [95%]", "SR p (McNemar)", "Discordant (A/B)", "ΔGC [95%]", "GC p (permutation)"]


def comparison_table(streams: Sequence[Stream], reference: str | None = None) -> Table | None:
    """Each method against a reference method (default: worldmind) on the same episodes."""
    pool = [s for s in streams if is_clean(s) and s.records]
    rows = []
    for (bench, planner, _judge), group in sorted(group_by(
            pool, lambda s: (s.spec.get("benchmark"), s.spec.get("planner"), s.judge)).items()):
        labels = sorted({s.label for s in group})
        ref = reference if reference in labels else ("worldmind" if "worldmind" in labels else labels[0])
        ref_streams = [s for s in group if s.label == ref]
        for other in labels:
            if other == ref:
                continue
            rows.append([bench, short_model(planner), ref, other,
                         *_diff_cells(ref_streams, [s for s in group if s.label == other])])
    if not rows:
        return None
    return Table("comparisons", "Paired comparisons of methods", ["Benchmark", "Backbone", "A", "B", *DIFF_COLS],
                 rows, caption="Methods compared on the same episodes. " + caption_facts(pool),
                 notes=[PAIRED_NOTE])


def twin_of(s: Stream, streams: Sequence[Stream], **overrides: Any) -> list[Stream]:
    """Streams identical to `s` (same seed too) except for the fields in `overrides`, set to those values:
    the stream `s` is compared with, episode by episode."""
    want = {**s.spec, "judge": s.judge, **overrides}
    keys = ("benchmark", "subset", "method", "options", "planner", "judge", "seed", "memory_from",
            "memory_budget", "perturb", "task_order_seed")
    return [o for o in streams if all(({**o.spec, "judge": o.judge}).get(k) == want.get(k) for k in keys)]


def _group_key(s: Stream) -> tuple[Any, ...]:
    return (s.spec.get("benchmark"), short_model(s.spec.get("planner")), s.label)


def _avg_cells(members: Sequence[Stream]) -> list[Num]:
    by_seed_sr = {seed: ep.avg_over_subsets(g, "SR") for seed, g in group_by(members, lambda s: s.spec.get("seed")).items()}
    by_seed_gc = {seed: ep.avg_over_subsets(g, "GC") for seed, g in group_by(members, lambda s: s.spec.get("seed")).items()}
    return [seed_summary(by_seed_sr), seed_summary(by_seed_gc)]


def robustness_table(streams: Sequence[Stream]) -> Table | None:
    """Object rename and memory poisoning against the same streams without the perturbation."""
    perturbed = [s for s in streams if s.spec.get("perturb") and s.spec.get("task_order_seed") is None]
    if not perturbed:
        return None
    rows: list[list[Any]] = []
    shown_clean: set[tuple[Any, ...]] = set()
    subsets_of: dict[tuple[Any, ...], set[str]] = {}
    for key, group in sorted(group_by(perturbed, lambda s: (*_group_key(s), s.spec.get("perturb"))).items()):
        clean = [c for s in group for c in twin_of(s, streams, perturb=None)]
        clean = list({c.stream_id + c.run: c for c in clean}.values())
        bench, planner, label, perturb = key
        subsets_of[key] = {str(s.spec.get("subset")) for s in group}
        if clean and (bench, planner, label) not in shown_clean:
            shown_clean.add((bench, planner, label))
            rows.append([bench, planner, label, "clean", *_avg_cells(clean), "", Num(0.0), "", "", Num(0.0), ""])
        diff = _diff_cells(group, clean) if clean else ["", None, None, "", None, None]
        rows.append([bench, planner, label, _perturb_name(perturb), *_avg_cells(group), *diff])
    cols = ["Benchmark", "Backbone", "Method", "Perturbation", "SR", "GC", *DIFF_COLS]
    notes = [PAIRED_NOTE, "Δ is perturbed minus clean on the same episodes; SR and GC are averages over the "
                          "subsets run (" + ", ".join(sorted({x for v in subsets_of.values() for x in v})) + ")."]
    return Table("robustness", "Adversarial robustness: object rename and memory poisoning", cols, rows,
                 caption="Robustness: object rename replaces object names with synonyms in env feedback and "
                         "observation text (actions and state untouched); memory poisoning replaces a share "
                         "of the loaded repository with wrong rules. " + caption_facts(perturbed),
                 notes=notes)


def _perturb_name(perturb: str) -> str:
    if perturb == "rename":
        return "object rename (synonyms)"
    if perturb.startswith("poison:"):
        return f"memory poison ({float(perturb.split(':', 1)[1]) * 100:g}% corrupted)"
    return perturb


def task_order_table(streams: Sequence[Stream]) -> Table | None:
    """SR and GC per task-order seed, and their mean ± sd over the permutations."""
    ordered = [s for s in streams if s.spec.get("task_order_seed") is not None and not s.spec.get("perturb")]
    if not ordered:
        return None
    order_seeds = sorted({int(s.spec["task_order_seed"]) for s in ordered})
    rows = []
    for (bench, planner, label, subset, seed), group in sorted(group_by(
            ordered, lambda s: (*_group_key(s), s.spec.get("subset"), s.spec.get("seed"))).items(), key=str):
        original = twin_of(group[0], streams, task_order_seed=None)
        by_order = {int(s.spec["task_order_seed"]): s for s in group}
        for metric in ("SR", "GC"):
            fn = ep.sr if metric == "SR" else ep.gc
            values = [fn(by_order[o].records).value if o in by_order else None for o in order_seeds]
            summary = mean_sd(values)
            orig = fn(original[0].records).value if original and original[0].records else None
            rows.append([bench, planner, label, subset, seed, metric, Num(orig), *(Num(v) for v in values),
                         Num(summary.mean, sd=summary.sd), summary.n_seeds])
    cols = ["Benchmark", "Backbone", "Method", "Subset", "Seed", "Metric", "Original order",
            *(f"Order seed {o}" for o in order_seeds), "Mean ± SD", "Orders"]
    return Table("task_order", "Task-order robustness", cols, rows,
                 caption="Task-order robustness: each task-order seed permutes the episode order of the stream "
                         "(memory accumulates in that order); mean ± sample sd over the permutations. "
                         + caption_facts(ordered))


_STREAM_IN_PATH = re.compile(r"streams/([^/]+)/memory/?$")


def source_label(s: Stream, streams: Sequence[Stream]) -> str:
    """Where a stream's seed memory came from, as "benchmark:planner" when that can be told.

    Reads, in order: the run's recorded memory-source facts (any of planner/benchmark-like keys), a
    loaded stream whose memory folder the path names, the stream id in the path; else the path itself.
    """
    facts = s.memory_source or {}
    planner = next((facts[k] for k in ("planner", "source_planner", "planner_model") if facts.get(k)), None)
    if not planner and isinstance(facts.get("planners"), list) and facts["planners"]:
        planner = ",".join(map(str, facts["planners"]))
    benches = facts.get("benchmarks") or ([facts["benchmark"]] if facts.get("benchmark") else [])
    path = str(s.spec.get("memory_from") or facts.get("path") or "")
    match = _STREAM_IN_PATH.search(path.replace("\\", "/"))
    if match:
        sid = match.group(1)
        for o in streams:
            if o.stream_id == sid and (o.folder is None or Path(path).resolve().parent == o.folder.resolve()
                                        or o.folder.name == sid):
                return f"{o.spec.get('benchmark')}:{short_model(o.spec.get('planner'))}"
        parts = sid.split(".")
        if len(parts) >= 4:
            return f"{parts[0]}:{parts[3]}"
    if planner or benches:
        return f"{','.join(map(str, benches)) or '?'}:{short_model(str(planner or '?'))}"
    return Path(path).name or path or "?"


def _target_label(s: Stream) -> str:
    return f"{s.spec.get('benchmark')}:{short_model(s.spec.get('planner'))}"


def transfer_matrix(streams: Sequence[Stream]) -> dict[tuple[str, str], dict[str, Any]]:
    """(source, target) -> SR/GC with the seed memory, from scratch, and the gain (averages over subsets)."""
    out: dict[tuple[str, str], dict[str, Any]] = {}
    moved = [s for s in streams if s.spec.get("memory_from") and not s.spec.get("perturb")]
    for (src, tgt, label), group in group_by(moved, lambda s: (source_label(s, streams), _target_label(s),
                                                               s.label)).items():
        scratch = list({c.run + c.stream_id: c for s in group
                        for c in twin_of(s, streams, memory_from=None)}.values())
        entry = {"method": label, "streams": group, "scratch": scratch,
                 "SR": ep.avg_over_subsets(group, "SR"), "GC": ep.avg_over_subsets(group, "GC"),
                 "SR_scratch": ep.avg_over_subsets(scratch, "SR") if scratch else None,
                 "GC_scratch": ep.avg_over_subsets(scratch, "GC") if scratch else None}
        for m in ("SR", "GC"):
            a, b = entry[m], entry[f"{m}_scratch"]
            entry[f"{m}_gain"] = round(a - b, 2) if a is not None and b is not None else None
        out[(src, tgt, label)] = entry  # type: ignore[index]
    return out


def transfer_table(streams: Sequence[Stream]) -> Table | None:
    matrix = transfer_matrix(streams)
    if not matrix:
        return None
    rows = []
    for (src, tgt, label), e in sorted(matrix.items()):  # type: ignore[misc]
        diff = _diff_cells(e["streams"], e["scratch"]) if e["scratch"] else ["", None, None, "", None, None]
        rows.append([src, tgt, label, Num(e["SR"]), Num(e["SR_scratch"]), Num(e["SR_gain"]), Num(e["GC"]),
                     Num(e["GC_scratch"]), Num(e["GC_gain"]), *diff])
    cols = ["Source memory", "Target", "Method", "SR", "SR from scratch", "SR gain", "GC", "GC from scratch",
            "GC gain", *DIFF_COLS]
    moved = [s for e in matrix.values() for s in e["streams"]]
    return Table("transfer", "Experience transfer (source -> target)", cols, rows,
                 caption="Transfer: the target stream starts from the source's repository (--memory-from); "
                         "gain over the same stream from scratch (empty memory), averages over subsets. "
                         + caption_facts(moved), notes=[PAIRED_NOTE])
