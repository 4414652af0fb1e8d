"""`--task-order-seed S`: the paper's task-order robustness check ("randomly permuting task order across
task_order_seed"). A stream's episodes run in a seeded permutation of their usual order, so its memory
accumulates in that order; the set of episodes (and each episode's own `index`, EmbodiedBench's episode
number) is unchanged, which keeps permuted and unpermuted streams comparable episode by episode.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeVar

import numpy as np

__all__ = ["task_order", "permute"]

T = TypeVar("T")


def task_order(n: int, seed: int) -> list[int]:
    """The permutation of positions 0..n-1 for `seed` (numpy's PCG64: the same on every machine)."""
    return [int(i) for i in np.random.default_rng(int(seed)).permutation(int(n))]


def permute(items: Sequence[T], seed: int | None) -> list[T]:
    """`items` in the order of `task_order(len(items), seed)`; unchanged for seed None."""
    if seed is None:
        return list(items)
    return [items[i] for i in task_order(len(items), seed)]
