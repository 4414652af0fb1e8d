"""One partition's vectors as contiguous float32 matrices: one matvec + argpartition per retrieval.

Retrieval runs once per planner call in every stream, so it must cost microseconds, not the milliseconds
a per-entry Python loop or a re-stacked matrix would. Rows are appended into matrices whose capacity
doubles (amortised O(1) appends), and a query scores every row with one matrix-vector product.
"""

from __future__ import annotations

import numpy as np

from worldmind_local.memory.entries import ExperienceEntry

__all__ = ["PartitionIndex"]


class PartitionIndex:
    """Entries of one partition with their key (instruction) and text embeddings, in insertion order."""

    def __init__(self, dim: int, capacity: int = 64) -> None:
        self.dim = dim
        self.n = 0
        self.keys = np.empty((capacity, dim), dtype=np.float32)
        self.texts = np.empty((capacity, dim), dtype=np.float32)
        self.entries: list[ExperienceEntry] = []
        self.by_instruction: dict[str, list[int]] = {}

    def __len__(self) -> int:
        return self.n

    def _reserve(self, rows: int) -> None:
        need = self.n + rows
        if need <= len(self.keys):
            return
        cap = max(need, 2 * len(self.keys), 64)
        for name in ("keys", "texts"):
            grown = np.empty((cap, self.dim), dtype=np.float32)
            grown[: self.n] = getattr(self, name)[: self.n]
            setattr(self, name, grown)

    def append(self, entry: ExperienceEntry, key: np.ndarray, text: np.ndarray) -> None:
        """Add one entry (stored without its embedding lists) and its unit vectors."""
        self.extend([entry], key[None, :], text[None, :])

    def extend(self, entries: list[ExperienceEntry], keys: np.ndarray, texts: np.ndarray) -> None:
        """Add many entries at once (loading a saved repository): no dedup, order kept."""
        self._reserve(len(entries))
        self.keys[self.n: self.n + len(entries)] = keys
        self.texts[self.n: self.n + len(entries)] = texts
        for i, entry in enumerate(entries, start=self.n):
            self.entries.append(entry)
            self.by_instruction.setdefault(entry.instruction, []).append(i)
        self.n += len(entries)

    def max_text_similarity(self, text: np.ndarray) -> float:
        """Highest cosine similarity of a unit text vector to the texts already here (-1 when empty)."""
        if self.n == 0:
            return -1.0
        return float(np.max(self.texts[: self.n] @ text))

    def top_k(self, query: np.ndarray, k: int, exclude_instruction: str | None = None) -> list[int]:
        """Row numbers of the k best keys by cosine, best first; equal scores keep insertion order."""
        n = self.n
        excluded = self.by_instruction.get(exclude_instruction, ()) if exclude_instruction is not None else ()
        k = min(k, n - len(excluded))
        if k <= 0:
            return []
        scores = self.keys[:n] @ query
        if excluded:
            scores[excluded] = -np.inf
        if k < n:
            kth = np.partition(scores, n - k)[n - k]          # the k-th largest score
            candidates = np.flatnonzero(scores >= kth)         # every row tied with it stays in the race
        else:
            candidates = np.arange(n)
        order = np.lexsort((candidates, -scores[candidates]))  # by score desc, then row asc
        return candidates[order[:k]].tolist()

    def copy(self) -> PartitionIndex:
        """Independent copy: the matrices are copied, the (frozen) entries shared."""
        other = PartitionIndex(self.dim, capacity=max(self.n, 64))
        other.keys[: self.n] = self.keys[: self.n]
        other.texts[: self.n] = self.texts[: self.n]
        other.n = self.n
        other.entries = list(self.entries)
        other.by_instruction = {key: list(rows) for key, rows in self.by_instruction.items()}
        return other
