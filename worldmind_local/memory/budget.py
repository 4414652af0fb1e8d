"""The memory-budget rule (the paper's MemN), shared by the WKR and the baselines' ExperienceStore.

First come, first kept; nothing is evicted. Unit `episodes` counts distinct source episodes (every entry
of an admitted episode enters), unit `entries` counts rows. Keeping this in one place is what makes a
loaded repository with a smaller budget keep exactly the prefix the policy would have kept.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterable

__all__ = ["BUDGET_UNITS", "over_budget", "budget_prefix"]

BUDGET_UNITS = ("episodes", "entries")


def over_budget(budget: int | None, unit: str, *, rows: int, sources: set[Hashable], source: Hashable) -> bool:
    """Whether a new entry from `source` must be refused by a memory holding `rows` entries from
    `sources`."""
    if budget is None:
        return False
    if unit == "entries":
        return rows >= budget
    return source not in sources and len(sources) >= budget


def budget_prefix(entry_sources: Iterable[Hashable], budget: int, unit: str) -> int:
    """How many leading entries (given their sources, in order) a memory of this budget keeps."""
    sources: set[Hashable] = set()
    kept = 0
    for source in entry_sources:
        if over_budget(budget, unit, rows=kept, sources=sources, source=source):
            break
        sources.add(source)
        kept += 1
    return kept
