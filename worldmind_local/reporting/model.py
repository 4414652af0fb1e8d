"""What a report is made of: tables of cells (numbers with their spread) and the facts behind a caption.

A `Table` holds typed cells, not strings: `Num` keeps the value, its sd over seeds or its interval and
the counts, so each renderer (Markdown, LaTeX, CSV, HTML) decides how to print it and the CSV keeps the
raw numbers. Helpers here group streams and compute per-episode quantities shared by the table
builders and the figures.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from worldmind_local.reporting.load import Stream
from worldmind_local.reporting.stats import mean_sd

__all__ = ["Num", "Table", "subset_order", "short_subset", "short_model", "caption_facts", "is_clean",
           "seed_summary", "SUBSET_SHORT"]

SUBSET_SHORT = {"base": "Base", "common_sense": "Common", "complex_instruction": "Complex",
                "visual_appearance": "Visual", "spatial": "Spatial", "long_horizon": "Long"}


@dataclass(frozen=True)
class Num:
    """A number cell. `sd` (over seeds) or `lo`/`hi` (an interval) say how sure it is; `n` counts seeds
    or episodes as `n_label` says; `p` is a p-value where the cell is a difference."""

    value: float | None
    sd: float | None = None
    lo: float | None = None
    hi: float | None = None
    n: int | None = None
    n_label: str = ""
    p: float | None = None
    digits: int = 1

    def text(self, pm: str = "±") -> str:
        if self.value is None:
            return "-"
        out = f"{self.value:.{self.digits}f}"
        if self.sd is not None:
            out += f" {pm} {self.sd:.{self.digits}f}"
        if self.lo is not None and self.hi is not None:
            out += f" [{self.lo:.{self.digits}f}, {self.hi:.{self.digits}f}]"
        if self.p is not None:
            out += f" (p={self.p:.3g})"
        return out


@dataclass
class Table:
    key: str                      # file stem, e.g. "main_eb_alfred"
    title: str
    columns: list[str]
    rows: list[list[Any]]         # cells: str, int, Num, or None
    caption: str = ""
    notes: list[str] = field(default_factory=list)
    header_groups: list[tuple[str, int]] = field(default_factory=list)   # spans over `columns`


def subset_order(benchmark: str, subsets: Iterable[str]) -> list[str]:
    """Subsets in the benchmark's own order (unknown ones last, sorted)."""
    wanted = set(subsets)
    try:
        from worldmind_local.registry import BENCHMARKS

        known = list(BENCHMARKS.get(benchmark).subsets)
    except Exception:  # a report never fails on a benchmark this install cannot import
        known = []
    return [s for s in known if s in wanted] + sorted(wanted - set(known))


def short_subset(subset: str) -> str:
    return SUBSET_SHORT.get(subset, subset.replace("_", " ").title())


def short_model(spec: str | None) -> str:
    return (spec or "").split(":", 1)[-1]


def is_clean(s: Stream) -> bool:
    """A plain stream: no seed memory, no perturbation, no task-order permutation, no memory budget."""
    return not any(s.spec.get(k) is not None for k in ("memory_from", "perturb", "task_order_seed", "memory_budget"))


def seed_summary(values_by_seed: dict[Any, float | None]) -> Num:
    summary = mean_sd(list(values_by_seed.values()))
    return Num(summary.mean, sd=summary.sd, n=summary.n_seeds, n_label="seeds")


def caption_facts(streams: Sequence[Stream]) -> str:
    """What was run, in one sentence: env (twin or real simulator), suite, models, streams, episodes."""
    if not streams:
        return "No streams."
    envs = sorted({s.env for s in streams})
    env_text = " and ".join("symbolic twin (not the real simulator)" if e == "twin" else f"real simulator ({e})"
                            for e in envs)
    suites = sorted({s.suite for s in streams if s.suite})
    planners = sorted({short_model(s.spec.get("planner")) for s in streams})
    judges = sorted({short_model(s.judge) for s in streams} - set(planners))
    episodes = sum(len(s.records) for s in streams)
    seeds = sorted({s.spec.get("seed") for s in streams}, key=str)
    runs = sorted({s.run for s in streams})
    text = (f"Env: {env_text}. Suite: {'; '.join(suites) or 'unknown'}. Planner: {', '.join(planners)}"
            + (f"; judge: {', '.join(judges)}" if judges else "")
            + f". {len(streams)} stream(s), {episodes} episode(s), seed(s) {', '.join(map(str, seeds))}; "
            f"run(s) {', '.join(runs)}.")
    return text
