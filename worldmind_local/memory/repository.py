"""The World Knowledge Repository (WKR): Process and Goal Experience, retrieved by task instruction.

Mechanics (paper Sec. 2 and Alg. 2):
- Two partitions, `process` (W_p, corrective rules) and `goal` (W_g, workflows).
- A new entry whose text has cosine similarity >= `dedup_threshold` (0.95) to the text of any entry of
  the SAME partition is discarded as a near-duplicate.
- Retrieval scores the current instruction's embedding against every entry's `instruction` embedding
  and returns the top k; equal scores keep insertion order. Goal retrieval passes `exclude_instruction`
  so a task never retrieves the workflow distilled from itself.

Budget policy (the paper's Mem-N ablation, "MemX indicates a maximum capacity of X experiences"):
`budget` caps the repository over both partitions together, in the unit `budget_unit`:
`episodes` (default; the paper's reading: an experience is what one task episode contributes, and the
WKR "is bounded by the number of tasks") counts distinct source episodes, so all the rules and the
workflow of an admitted episode enter together; `entries` counts single entries (each rule is one).
Entries are admitted first come, first kept: once the cap is reached every later candidate from a new
source is refused (and counted in `rejected_budget`); nothing is evicted. The paper describes no eviction rule, its Mem-N repositories
grow with the task sequence until they reach N, and refusing keeps the repository a pure function of the
episode order, which is what makes a resumed or replayed run reproduce it exactly. `budget=0` is Mem0
(no memory); `budget=None` is unbounded. Loading a saved repository with a smaller budget keeps its
first `budget` entries, the same ones the policy would have kept.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from typing import Any

import numpy as np

from worldmind_local.memory.budget import BUDGET_UNITS, budget_prefix, over_budget
from worldmind_local.memory.embedder import (
    DEFAULT_DIM,
    DEFAULT_MODEL_ID,
    Embedder,
    matching_default_embedder,
)
from worldmind_local.memory.entries import PARTITIONS, ExperienceEntry, MemoryDataError
from worldmind_local.memory.index import PartitionIndex
from worldmind_local.memory.storage import (
    UNSET,
    as_single_dataset,
    atomic_save_dataset,
    build_dataset,
    load_saved_dataset,
    read_dataset,
    read_metadata,
    resolve_settings,
)

__all__ = ["WorldKnowledgeRepository"]

# Similarities are float32 dot products; this absorbs their rounding so "exactly 0.95" counts as >= 0.95.
_SIMILARITY_EPS = 1e-6


class WorldKnowledgeRepository:
    """Process + Goal Experience with near-duplicate filtering, an optional budget, and fast top-k."""

    def __init__(self, embedder: Embedder | None = None, *, budget: int | None = None,
                 dedup_threshold: float = 0.95, budget_unit: str = "episodes") -> None:
        if budget is not None and budget < 0:
            raise ValueError(f"memory budget must be >= 0 or None, got {budget}")
        if budget_unit not in BUDGET_UNITS:
            raise ValueError(f"budget_unit must be 'episodes' or 'entries', got {budget_unit!r}")
        self.budget_unit = budget_unit
        self._sources: set[tuple[str, ...]] = set()
        # (episode index, rows after its commit) per committed stream episode: lets a resumed run cut
        # the repository back to exactly the episodes whose records are on disk.
        self.commits: list[list[int]] = []
        if not 0.0 < dedup_threshold <= 1.0:
            raise ValueError(f"dedup_threshold must be in (0, 1], got {dedup_threshold}")
        self._embedder = embedder
        self.budget = budget
        self.dedup_threshold = float(dedup_threshold)
        self.dim = embedder.dim if embedder is not None else DEFAULT_DIM
        self.embedder_model_id = embedder.model_id if embedder is not None else DEFAULT_MODEL_ID
        self._parts = {p: PartitionIndex(self.dim) for p in PARTITIONS}
        self._order: list[tuple[str, int]] = []   # (partition, row) of every entry, in insertion order
        self.rejected_duplicates = 0
        self.rejected_budget = 0

    @property
    def embedder(self) -> Embedder:
        """The embedder in use; without one given, the shared default all-MiniLM-L6-v2 (loaded lazily)."""
        if self._embedder is None:
            self._embedder = matching_default_embedder(self.embedder_model_id, self.dim, "repository")
        return self._embedder

    # -- adding -------------------------------------------------------------------------------------

    async def embed(self, entries: Iterable[ExperienceEntry]) -> list[ExperienceEntry]:
        """The entries with any missing embedding computed (one batched encode for all of them)."""
        entries = list(entries)
        wanted = [e.instruction for e in entries if e.key_embedding is None]
        wanted += [e.text for e in entries if e.text_embedding is None]
        if not wanted:
            return entries
        unique = list(dict.fromkeys(wanted))
        vectors = await self.embedder.aencode(unique)
        lookup = dict(zip(unique, vectors, strict=True))
        out = []
        for e in entries:
            update: dict[str, Any] = {}
            if e.key_embedding is None:
                update["key_embedding"] = lookup[e.instruction].tolist()
            if e.text_embedding is None:
                update["text_embedding"] = lookup[e.text].tolist()
            out.append(e.model_copy(update=update) if update else e)
        return out

    async def add(self, entries: Iterable[ExperienceEntry]) -> list[bool]:
        """Embed what is missing, then `add_embedded` each entry in order; True where it was kept."""
        return [self.add_embedded(e) for e in await self.embed(entries)]

    def add_embedded(self, entry: ExperienceEntry) -> bool:
        """Add an entry that carries both embeddings; False for a near-duplicate or over the budget."""
        key = self._unit(entry, "key_embedding")
        text = self._unit(entry, "text_embedding")
        part = self._parts[entry.partition]
        if part.max_text_similarity(text) >= self.dedup_threshold - _SIMILARITY_EPS:
            self.rejected_duplicates += 1
            return False
        source = _source(entry)
        if over_budget(self.budget, self.budget_unit, rows=len(self._order), sources=self._sources, source=source):
            self.rejected_budget += 1
            return False
        part.append(entry.without_embeddings(), key, text)
        self._order.append((entry.partition, part.n - 1))
        self._sources.add(source)
        return True

    @staticmethod
    def entry_from_record(item: dict[str, Any]) -> ExperienceEntry:
        """An entry from its episodes.jsonl form (no vectors; `embed` computes them)."""
        return ExperienceEntry(**item)

    def commit(self, episode: int) -> None:
        """Mark the end of one stream episode's additions (see `truncate_to_commits`)."""
        self.commits.append([int(episode), len(self._order)])

    def truncated(self, rows: int) -> WorldKnowledgeRepository:
        """A copy holding only the first `rows` entries in insertion order (exact: dedup and budget
        decisions depend only on the entries before)."""
        kept = self.entries(with_embeddings=True)[:rows]
        other = WorldKnowledgeRepository(self._embedder, budget=self.budget, dedup_threshold=self.dedup_threshold,
                                         budget_unit=self.budget_unit)
        other.dim, other.embedder_model_id = self.dim, self.embedder_model_id
        if kept:
            keys = np.asarray([e.key_embedding for e in kept], dtype=np.float32)
            texts = np.asarray([e.text_embedding for e in kept], dtype=np.float32)
            other._bulk_insert([e.without_embeddings() for e in kept], keys, texts)
        other.commits = [c for c in self.commits if c[1] <= rows]
        other.rejected_duplicates, other.rejected_budget = self.rejected_duplicates, self.rejected_budget
        return other

    def _unit(self, entry: ExperienceEntry, field: str) -> np.ndarray:
        value = getattr(entry, field)
        if value is None:
            raise ValueError(f"entry {entry.id}: {field} is missing; use `await repository.add([...])` to embed")
        vec = np.asarray(value, dtype=np.float32)
        if vec.shape != (self.dim,):
            raise ValueError(f"entry {entry.id}: {field} has shape {vec.shape}, this repository uses {self.dim}")
        norm = float(np.linalg.norm(vec))
        if not np.isfinite(norm) or norm == 0.0:
            raise ValueError(f"entry {entry.id}: {field} is zero or not finite")
        # the embedder's vectors are already unit length: keep them bit-exact
        return vec if abs(norm - 1.0) <= 1e-4 else vec / np.float32(norm)

    # -- reading ------------------------------------------------------------------------------------

    def retrieve(self, query: np.ndarray, partition: str, k: int, *,
                 exclude_instruction: str | None = None) -> list[ExperienceEntry]:
        """Top-k entries of `partition` by cosine(query, instruction embedding), best first.

        `query` is the embedding of the current task's instruction (computed once per episode).
        Entries whose instruction equals `exclude_instruction` are skipped.
        """
        part = self._partition(partition)
        q = np.asarray(query, dtype=np.float32).reshape(-1)
        if q.shape != (self.dim,):
            raise ValueError(f"retrieve: query has {q.size} values, this repository uses {self.dim}")
        norm = float(np.linalg.norm(q))
        if norm > 0.0 and abs(norm - 1.0) > 1e-4:
            q = q / np.float32(norm)
        return [part.entries[row] for row in part.top_k(q, k, exclude_instruction)]

    def entries(self, partition: str | None = None, *, with_embeddings: bool = False) -> list[ExperienceEntry]:
        """Entries in insertion order (one partition, or all). Vectors live in matrices, so entries come
        without embedding lists unless `with_embeddings=True`."""
        if partition is not None:
            part = self._partition(partition)
            pairs = [(partition, row) for row in range(part.n)]
        else:
            pairs = self._order
        if not with_embeddings:
            return [self._parts[p].entries[row] for p, row in pairs]
        return [
            self._parts[p].entries[row].model_copy(update={
                "key_embedding": self._parts[p].keys[row].tolist(),
                "text_embedding": self._parts[p].texts[row].tolist(),
            })
            for p, row in pairs
        ]

    def _partition(self, partition: str) -> PartitionIndex:
        try:
            return self._parts[partition]
        except KeyError:
            raise ValueError(f"unknown partition {partition!r}; expected one of {PARTITIONS}") from None

    def __len__(self) -> int:
        return len(self._order)

    def counts(self) -> dict[str, int]:
        """Entries per partition."""
        return {p: part.n for p, part in self._parts.items()}

    def __repr__(self) -> str:
        return (f"WorldKnowledgeRepository({self.counts()}, budget={self.budget}, "
                f"dedup_threshold={self.dedup_threshold}, embedder={self.embedder_model_id!r})")

    def copy(self) -> WorldKnowledgeRepository:
        """An independent snapshot (for waves): adding to one never changes the other."""
        other = WorldKnowledgeRepository(self._embedder, budget=self.budget, dedup_threshold=self.dedup_threshold,
                                         budget_unit=self.budget_unit)
        other.dim, other.embedder_model_id = self.dim, self.embedder_model_id
        other._parts = {p: part.copy() for p, part in self._parts.items()}
        other._order = list(self._order)
        other._sources = set(self._sources)
        other.commits = [list(c) for c in self.commits]
        other.rejected_duplicates, other.rejected_budget = self.rejected_duplicates, self.rejected_budget
        return other

    # -- persistence --------------------------------------------------------------------------------

    def metadata(self) -> dict[str, Any]:
        return {"embedder_model_id": self.embedder_model_id, "dim": self.dim,
                "dedup_threshold": self.dedup_threshold, "budget": self.budget, "budget_unit": self.budget_unit,
                "counts": self.counts(), "commits": self.commits}

    def to_dataset(self) -> Any:
        """A `datasets.Dataset`, one row per entry in insertion order, embeddings as float32 lists."""
        n = len(self._order)
        keys = np.empty((n, self.dim), dtype=np.float32)
        texts = np.empty((n, self.dim), dtype=np.float32)
        partitions = np.array([p for p, _ in self._order], dtype=object)
        for name, part in self._parts.items():
            where = np.flatnonzero(partitions == name) if n else np.zeros(0, dtype=np.int64)
            keys[where] = part.keys[: part.n]
            texts[where] = part.texts[: part.n]
        return build_dataset(self.entries(), keys, texts, self.metadata())

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write to `path` atomically (old or new, never half written); readable by `load_from_disk`."""
        atomic_save_dataset(self.to_dataset(), path)

    @classmethod
    def load(cls, path: Any, embedder: Embedder | None = None, **kw: Any) -> WorldKnowledgeRepository:
        """From a folder written by `save` (or any `save_to_disk` folder, Dataset or DatasetDict)."""
        if not isinstance(path, (str, os.PathLike)):
            return cls.from_dataset(path, embedder, **kw)
        if not os.path.isdir(path):
            raise FileNotFoundError(f"no World Knowledge Repository at {path}")
        return cls.from_dataset(load_saved_dataset(path), embedder, where=str(path), **kw)

    @classmethod
    def from_dataset(cls, dataset: Any, embedder: Embedder | None = None, *, where: str = "dataset",
                     budget: int | None = UNSET, dedup_threshold: float = UNSET,
                     budget_unit: str | None = None) -> WorldKnowledgeRepository:
        """Rebuild from rows in order, without re-running dedup (a saved repository is already deduped).

        Settings not passed come from the stored metadata. Null embeddings are computed with the
        embedder; more rows than `budget` keeps the first `budget`.
        """
        dataset = as_single_dataset(dataset)
        meta = read_metadata(dataset)
        settings = resolve_settings(meta, dataset, embedder, where, budget, dedup_threshold)
        unit = budget_unit or meta.get("budget_unit") or "entries"
        repo = cls(embedder, budget=settings["budget"], dedup_threshold=settings["dedup_threshold"], budget_unit=unit)
        repo.dim, repo.embedder_model_id = settings["dim"], settings["embedder_model_id"]
        commits = meta.get("commits")
        repo.commits = [list(map(int, c)) for c in commits] if isinstance(commits, list) else []
        repo._parts = {p: PartitionIndex(repo.dim) for p in PARTITIONS}
        entries, keys, texts = read_dataset(dataset, where, repo.dim)
        if repo.budget is not None:
            cut = budget_prefix((_source(e) for e in entries), repo.budget, repo.budget_unit)
            entries, keys, texts = entries[:cut], keys[:cut], texts[:cut]
        repo._fill_missing(entries, keys, texts)
        repo._bulk_insert(entries, keys, texts)
        return repo

    def _fill_missing(self, entries: list[ExperienceEntry], keys: np.ndarray, texts: np.ndarray) -> None:
        """Compute embeddings that a hand-made dataset left null (synchronously: loading is not async)."""
        for matrix, attr in ((keys, "instruction"), (texts, "text")):
            rows = np.flatnonzero(np.isnan(matrix).any(axis=1))
            if rows.size:
                matrix[rows] = self.embedder.encode([getattr(entries[r], attr) for r in rows])

    def _bulk_insert(self, entries: list[ExperienceEntry], keys: np.ndarray, texts: np.ndarray) -> None:
        for matrix in (keys, texts):
            norms = np.linalg.norm(matrix, axis=1, keepdims=True)
            if (norms == 0).any():
                raise MemoryDataError("repository", "embedding", "an embedding is all zeros")
            off = np.abs(norms[:, 0] - 1.0) > 1e-4
            matrix[off] /= norms[off]
        partitions = np.array([e.partition for e in entries], dtype=object)
        for name, part in self._parts.items():
            rows = np.flatnonzero(partitions == name) if entries else np.zeros(0, dtype=np.int64)
            part.extend([entries[r] for r in rows], keys[rows], texts[rows])
        seen = dict.fromkeys(PARTITIONS, 0)
        for e in entries:
            self._order.append((e.partition, seen[e.partition]))
            self._sources.add(_source(e))
            seen[e.partition] += 1


def _source(entry: ExperienceEntry) -> tuple[str, ...]:
    """The episode an entry came from (the unit of an `episodes` budget)."""
    return (entry.run_id, entry.benchmark, entry.subset, entry.task_id, str(entry.episode))
