"""Choosing few-shot worked examples from a benchmark's pool (the part every benchmark shares).

Each benchmark builds its own pool (`benchmarks/eb_*/examples.py`: expert plans replayed on its twin,
ordered by how much of each plan is predicted) and asks `pick` for the first `n` usable examples: one per
underlying episode and one per instruction, never the evaluated task (its id or instruction, compared
after `norm`), nor an episode the benchmark says is the same one under another subset (`banned`).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any, Protocol

from worldmind_local.env import WorkedExample

__all__ = ["norm", "pick", "pool_root"]


class _Candidate(Protocol):
    example: WorkedExample
    episode: str


def norm(text: str) -> str:
    """Case, spacing and a final full stop do not make a different instruction."""
    return " ".join(str(text).casefold().split()).rstrip(".").strip()


def pool_root(adapter: Any, data_dir: Path | None) -> str | None:
    """The data pack's resolved path when it holds this benchmark's data, else None (generated pool)."""
    if data_dir is None or not adapter.has_data(Path(data_dir)):
        return None
    return str(Path(data_dir).resolve())


def pick(pool: Iterable[_Candidate], n: int, excluded: frozenset[str],
         banned: frozenset[str] = frozenset()) -> tuple[WorkedExample, ...]:
    """The first `n` examples of `pool` that are neither repeats nor the evaluated task."""
    out: list[WorkedExample] = []
    seen: set[str] = set()
    for cand in pool:
        ex = cand.example
        instruction = norm(ex.instruction)
        if cand.episode in seen or instruction in seen:
            continue
        seen |= {cand.episode, instruction}
        if cand.episode in banned or norm(ex.task_id) in excluded or instruction in excluded:
            continue
        out.append(ex)
        if len(out) == n:
            break
    return tuple(out)
