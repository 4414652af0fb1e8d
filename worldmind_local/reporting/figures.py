"""The report's figures with matplotlib (Agg backend: no display needed), each as PNG and SVG.

- SR/GC bars per benchmark with 95% intervals (pooled episodes over seeds: Wilson for SR, bootstrap for
  GC, stratified bootstrap for the average);
- the memory-budget curve (SR and GC average vs MemN, one line per top-k);
- the transfer heatmap (source repository x target, SR gain over the same stream from scratch);
- taxonomy bars (how episodes ended, per method);
- learning curves: cumulative SR over the episode order of each stream (memory accumulates in this order).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import worldmind_local.reporting.episodes as ep
from worldmind_local.reporting.load import Stream
from worldmind_local.reporting.model import caption_facts, is_clean, short_model, short_subset
from worldmind_local.reporting.tables import _budget_pool, _top_k, group_by, subset_columns
from worldmind_local.reporting.tables_paired import transfer_matrix

__all__ = ["Figure", "make_figures"]


@dataclass
class Figure:
    key: str
    title: str
    caption: str
    files: list[Path]


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.hashsalt": "worldmind", "figure.dpi": 110, "font.size": 9})
    return plt


def _save(fig: Any, out: Path, key: str) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for ext in ("png", "svg"):
        path = out / f"{key}.{ext}"
        fig.savefig(path, bbox_inches="tight", metadata={"Date": None} if ext == "svg" else None)
        files.append(path)
    _plt().close(fig)
    return files


def _err(est: Any) -> tuple[float, float]:
    if est.value is None or est.lo is None:
        return (0.0, 0.0)
    return (max(0.0, est.value - est.lo), max(0.0, est.hi - est.value))


def _bars(streams: Sequence[Stream], out: Path) -> list[Figure]:
    plt = _plt()
    figures = []
    clean = [s for s in streams if is_clean(s) and s.records]
    for bench, group in sorted(group_by(clean, lambda s: s.spec.get("benchmark")).items()):
        subsets = subset_columns(bench, group)
        several = len({short_model(s.spec.get("planner")) for s in group}) > 1
        series = group_by(group, lambda s, several=several: s.label + (
            f" ({short_model(s.spec.get('planner'))})" if several else ""))
        fig, axes = plt.subplots(1, 2, figsize=(max(6, 1.4 * (len(subsets) + 1) * 2), 3.4), sharey=True)
        x = np.arange(len(subsets) + 1)
        width = 0.8 / max(1, len(series))
        for ax, metric in zip(axes, ("SR", "GC"), strict=True):
            for i, (label, members) in enumerate(sorted(series.items())):
                ests = []
                for sub in subsets:
                    recs = [r for s in members if s.spec.get("subset") == sub for r in s.records]
                    ests.append((ep.sr if metric == "SR" else ep.gc)(recs))
                ests.append(ep.pooled_avg(members, metric))
                heights = [e.value or 0.0 for e in ests]
                errs = np.array([_err(e) for e in ests]).T
                ax.bar(x + (i - (len(series) - 1) / 2) * width, heights, width, yerr=errs, capsize=2, label=label)
            ax.set_xticks(x, [*(short_subset(s) for s in subsets), "Avg"])
            ax.set_title(f"{metric} (%)")
            ax.set_ylim(0, 105)
        axes[0].legend(fontsize=7, loc="upper left")
        fig.suptitle(f"{bench}: SR and GC with 95% intervals")
        key = f"bars_{bench}"
        figures.append(Figure(key, f"SR/GC on {bench}", "Bars: pooled episodes over seeds; error bars: Wilson 95% "
                              "(SR), bootstrap 95% (GC), stratified bootstrap (Avg). " + caption_facts(group),
                              _save(fig, out, key)))
    return figures


def _budget(streams: Sequence[Stream], out: Path) -> list[Figure]:
    plt = _plt()
    pool = [s for s in _budget_pool(streams) if s.records]
    figures = []
    for (bench, planner, method), group in sorted(group_by(
            pool, lambda s: (s.spec.get("benchmark"), s.spec.get("planner"), s.spec.get("method"))).items()):
        budgets = sorted({s.spec.get("memory_budget") for s in group if s.spec.get("memory_budget") is not None})
        position = {b: i for i, b in enumerate(budgets)}
        position[None] = len(budgets)
        fig, axes = plt.subplots(1, 2, figsize=(8, 3.2))
        for k, members in sorted(group_by(group, lambda s: _top_k(s) or 0).items()):
            for ax, metric in zip(axes, ("SR", "GC"), strict=True):
                points = sorted((position[b], ep.pooled_avg(m, metric))
                                for b, m in group_by(members, lambda s: s.spec.get("memory_budget")).items())
                xs = [p for p, _ in points]
                ys = [e.value if e.value is not None else math.nan for _, e in points]
                errs = np.array([_err(e) for _, e in points]).T
                ax.errorbar(xs, ys, yerr=errs, marker="o", capsize=3, label=f"top-{k}")
        labels = [f"Mem{b}" for b in budgets] + (["Mem∞"] if any(s.spec.get("memory_budget") is None
                                                                 for s in group) else [])
        for ax, metric in zip(axes, ("SR", "GC"), strict=True):
            ax.set_xticks(range(len(labels)), labels)
            ax.set_title(f"{metric} avg (%)")
            ax.legend(fontsize=7)
        key = f"memory_budget_{bench}_{short_model(planner)}_{method}".replace("/", "_")
        figures.append(Figure(key, f"Memory budget ({bench}, {method})", "Average over subsets vs memory budget, "
                              "one line per retrieval size; 95% stratified bootstrap intervals. "
                              + caption_facts(group), _save(fig, out, key)))
    return figures


def _transfer(streams: Sequence[Stream], out: Path) -> list[Figure]:
    matrix = transfer_matrix(streams)
    if not matrix:
        return []
    plt = _plt()
    sources = sorted({k[0] for k in matrix})
    targets = sorted({k[1] for k in matrix})
    gain = all(e["SR_gain"] is not None for e in matrix.values())
    grid = np.full((len(sources), len(targets)), np.nan)
    for (src, tgt, _label), e in matrix.items():  # type: ignore[misc]
        value = e["SR_gain"] if gain else e["SR"]
        if value is not None and math.isnan(grid[sources.index(src), targets.index(tgt)]):
            grid[sources.index(src), targets.index(tgt)] = value
    fig, ax = plt.subplots(figsize=(1.6 * len(targets) + 2.5, 0.8 * len(sources) + 1.8))
    bound = max(1.0, float(np.nanmax(np.abs(grid)))) if np.isfinite(grid).any() else 1.0
    im = ax.imshow(grid, cmap="RdBu" if gain else "viridis", vmin=-bound if gain else 0, vmax=bound if gain else 100)
    for i in range(len(sources)):
        for j in range(len(targets)):
            if np.isfinite(grid[i, j]):
                ax.text(j, i, f"{grid[i, j]:+.1f}" if gain else f"{grid[i, j]:.1f}", ha="center", va="center")
    ax.set_xticks(range(len(targets)), targets, rotation=20, ha="right")
    ax.set_yticks(range(len(sources)), sources)
    ax.set_xlabel("target (benchmark:planner)")
    ax.set_ylabel("source memory")
    fig.colorbar(im, ax=ax, label="SR gain over from-scratch (pp)" if gain else "SR (%)")
    moved = [s for e in matrix.values() for s in e["streams"]]
    return [Figure("transfer_heatmap", "Transfer heatmap", ("SR gain over the same stream from scratch"
                   if gain else "SR with the transferred memory") + " (average over subsets). " + caption_facts(moved),
                   _save(fig, out, "transfer_heatmap"))]


def _taxonomy(streams: Sequence[Stream], out: Path) -> list[Figure]:
    pool = [s for s in streams if is_clean(s) and s.records]
    if not pool:
        return []
    plt = _plt()
    groups = group_by(pool, lambda s: f"{s.spec.get('benchmark')}\n{s.label}\n{short_model(s.spec.get('planner'))}")
    names = sorted(groups)
    fig, ax = plt.subplots(figsize=(max(5, 1.3 * len(names)), 3.6))
    bottom = np.zeros(len(names))
    for cat in ep.TAXONOMY:
        counts = np.array([ep.taxonomy(r for s in groups[n] for r in s.records).get(cat, 0) for n in names], float)
        ax.bar(names, counts, bottom=bottom, label=cat.replace("_", " "))
        bottom += counts
    ax.set_ylabel("episodes")
    ax.legend(fontsize=7, bbox_to_anchor=(1.01, 1), loc="upper left")
    ax.tick_params(axis="x", labelsize=7)
    return [Figure("taxonomy", "Error taxonomy", "How episodes ended, per method (summed over subsets and seeds). "
                   + caption_facts(pool), _save(fig, out, "taxonomy"))]


def _learning(streams: Sequence[Stream], out: Path) -> list[Figure]:
    plt = _plt()
    figures = []
    with_records = [s for s in streams if s.records]
    for bench, group in sorted(group_by(with_records, lambda s: s.spec.get("benchmark")).items()):
        fig, ax = plt.subplots(figsize=(7, 3.6))
        for s in sorted(group, key=lambda s: s.stream_id):
            wins = np.cumsum(ep.successes(s.records), dtype=float)
            curve = 100 * wins / np.arange(1, len(wins) + 1)
            extra = "".join(f" {k}={s.spec[k]}" for k in ("perturb", "task_order_seed", "memory_budget")
                            if s.spec.get(k) is not None)
            ax.plot(np.arange(1, len(curve) + 1), curve, marker=".", linewidth=1,
                    label=f"{s.label} {s.spec.get('subset')} s{s.spec.get('seed')}{extra}")
        ax.set_xlabel("episode (order run)")
        ax.set_ylabel("cumulative SR (%)")
        ax.set_ylim(-3, 103)
        if len(group) <= 16:
            ax.legend(fontsize=6, bbox_to_anchor=(1.01, 1), loc="upper left")
        key = f"learning_{bench}"
        figures.append(Figure(key, f"Learning curves on {bench}", "Cumulative SR over the episode order of each "
                              "stream (memory accumulates in this order). " + caption_facts(group),
                              _save(fig, out, key)))
    return figures


def make_figures(streams: Sequence[Stream], out: str | Path) -> list[Figure]:
    out = Path(out)
    figures: list[Figure] = []
    for build in (_bars, _budget, _transfer, _taxonomy, _learning):
        figures += build(streams, out)
    return figures
