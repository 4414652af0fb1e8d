"""The baselines' memory: an `ExperienceStore` of `StoredExperience` rows, retrieved by instruction.

NaiveMem, Synapse, AWM and ReasoningBank (baselines.md §5-§8) keep different things (raw trajectories,
exemplars, workflow texts, reasoning items) but need the same mechanics, which this module gives them
once, with the World Knowledge Repository's conventions so the runner treats both alike (the `Memory`
protocol):

- One row per entry, in insertion order, each with its provenance and the signal its write was
  decided by (`success`, `success_signal`); `kind` says what the row is.
- Retrieval scores the query vector against each row's `key_embedding` (the embedding of `key`, which
  is the source task's instruction unless a method sets another key, e.g. Synapse's specifier) by
  cosine, best first, equal scores in insertion order. `exclude_instruction` skips rows whose
  *normalised* instruction (case, whitespace and a trailing full stop ignored) equals it: C4's
  self-exclusion, slightly broader than the WKR's exact match so that trivially re-spelled duplicates of
  the evaluated task are skipped too.
- Budget: the WKR's (`budget_unit` "episodes" counts distinct source episodes, "entries" counts rows);
  first come, first kept, nothing evicted; `budget=0` keeps nothing, None is unbounded; loading with a
  smaller budget keeps the same prefix the policy would have kept.
- Dedup: none by default (ReasoningBank: "no deduplication"); `dedup="text"` refuses a row whose exact
  text is already stored (NaiveMem, §8). No text embedding is kept: an exact check needs none.
- Saved as a plain Hugging Face dataset (`datasets.load_from_disk(path)` opens it) with the same atomic
  save as the WKR; settings and the commit log travel as JSON in `info.description`.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterable
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, model_validator

from worldmind_local.memory.budget import BUDGET_UNITS, over_budget
from worldmind_local.memory.embedder import (
    DEFAULT_DIM,
    DEFAULT_MODEL_ID,
    Embedder,
    matching_default_embedder,
)
from worldmind_local.memory.entries import MemoryDataError
from worldmind_local.memory.storage import UNSET, atomic_save_dataset, resolve_settings

__all__ = ["FORMAT", "StoredExperience", "ExperienceStore", "normalize_instruction", "Dedup"]

FORMAT = "worldmind_local.store/1"
Dedup = Literal["none", "text"]
BudgetUnit = Literal["episodes", "entries"]

# What makes a row distinct (the vector is derived data and stays out of the id).
_ID_FIELDS = (
    "kind", "text", "instruction", "key", "benchmark", "subset", "episode", "task_id", "success",
    "success_signal", "title", "description", "planner_model", "judge_model", "run_id",
)
_INT_FIELDS = ("episode",)
_BOOL_FIELDS = ("success",)


def normalize_instruction(text: str) -> str:
    """The form two instructions are compared in for self-exclusion (C4)."""
    return " ".join(text.casefold().split()).rstrip(" .")


def stored_id(fields: dict[str, Any]) -> str:
    """A deterministic id from the row's content and provenance (never the wall clock)."""
    parts = ["" if fields.get(name) is None else str(fields.get(name)) for name in _ID_FIELDS]
    return hashlib.sha256(json.dumps(parts, ensure_ascii=False).encode("utf-8")).hexdigest()[:20]


class StoredExperience(BaseModel):
    """One row of a baseline's memory: what was kept, from which episode, under which success signal.

    `text` is the row's payload (a rendered trajectory, an exemplar, a workflow text, a memory item's
    content); `title`/`description` are ReasoningBank's item fields. `key` is the text whose embedding
    (`key_embedding`) retrieval compares against ("" = the instruction).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str = ""
    kind: str
    text: str
    instruction: str
    key: str = ""
    benchmark: str
    subset: str
    episode: int
    task_id: str
    success: bool | None = None
    success_signal: str = ""
    title: str | None = None
    description: str | None = None
    planner_model: str = ""
    judge_model: str = ""
    run_id: str = ""
    key_embedding: list[float] | None = None   # embedding of `key_text` (retrieval)

    @model_validator(mode="before")
    @classmethod
    def _fill_id(cls, data: Any) -> Any:
        if isinstance(data, dict) and not data.get("id"):
            data = {**data, "id": stored_id(data)}
        return data

    @property
    def key_text(self) -> str:
        return self.key or self.instruction

    @property
    def source(self) -> tuple[str, ...]:
        """The episode a row came from (the unit of an `episodes` budget and of grouped retrieval)."""
        return (self.run_id, self.benchmark, self.subset, self.task_id, str(self.episode))

    def without_embeddings(self) -> StoredExperience:
        return self if self.key_embedding is None else self.model_copy(update={"key_embedding": None})


_COLUMNS = tuple(f for f in StoredExperience.model_fields if f != "key_embedding")


class ExperienceStore:
    """Rows with instruction-key vectors; exact top-k retrieval, budget, optional exact-text dedup."""

    def __init__(self, embedder: Embedder | None = None, *, budget: int | None = None,
                 budget_unit: str = "episodes", dedup: str = "none") -> None:
        if budget is not None and budget < 0:
            raise ValueError(f"memory budget must be >= 0 or None, got {budget}")
        if budget_unit not in BUDGET_UNITS:
            raise ValueError(f"budget_unit must be 'episodes' or 'entries', got {budget_unit!r}")
        if dedup not in ("none", "text"):
            raise ValueError(f"dedup must be 'none' or 'text', got {dedup!r}")
        self._embedder = embedder
        self.budget, self.budget_unit, self.dedup = budget, budget_unit, dedup
        self.dim = embedder.dim if embedder is not None else DEFAULT_DIM
        self.embedder_model_id = embedder.model_id if embedder is not None else DEFAULT_MODEL_ID
        self._rows: list[StoredExperience] = []
        self._keys = np.zeros((0, self.dim), dtype=np.float32)
        self._n = 0
        self._sources: set[tuple[str, ...]] = set()
        self._texts: set[str] = set()
        self.commits: list[list[int]] = []   # [episode index, rows after its commit]
        self.rejected_duplicates = 0
        self.rejected_budget = 0

    @property
    def embedder(self) -> Embedder:
        """The embedder in use; without one given, the shared default all-MiniLM-L6-v2 (lazily)."""
        if self._embedder is None:
            self._embedder = matching_default_embedder(self.embedder_model_id, self.dim, "store")
        return self._embedder

    # -- adding -------------------------------------------------------------------------------------

    async def embed(self, entries: Iterable[StoredExperience]) -> list[StoredExperience]:
        """The entries with a missing `key_embedding` computed (one batched encode)."""
        entries = list(entries)
        wanted = list(dict.fromkeys(e.key_text for e in entries if e.key_embedding is None))
        if not wanted:
            return entries
        lookup = dict(zip(wanted, await self.embedder.aencode(wanted), strict=True))
        return [e if e.key_embedding is not None else e.model_copy(update={"key_embedding": lookup[e.key_text].tolist()})
                for e in entries]

    async def add(self, entries: Iterable[StoredExperience]) -> list[bool]:
        """Embed what is missing, then `add_embedded` each in order (tests and tools; the runner embeds
        and adds itself)."""
        return [self.add_embedded(e) for e in await self.embed(entries)]

    def add_embedded(self, entry: StoredExperience) -> bool:
        """Add an embedded entry; False for an exact duplicate (dedup="text") or over the budget."""
        key = self._unit(entry)
        if self.dedup == "text" and entry.text in self._texts:
            self.rejected_duplicates += 1
            return False
        if over_budget(self.budget, self.budget_unit, rows=self._n, sources=self._sources, source=entry.source):
            self.rejected_budget += 1
            return False
        self._append(entry.without_embeddings(), key)
        return True

    def _append(self, entry: StoredExperience, key: np.ndarray) -> None:
        if self._n == len(self._keys):   # amortised growth: a save per episode must stay cheap
            grown = np.zeros((max(8, 2 * len(self._keys)), self.dim), dtype=np.float32)
            grown[: self._n] = self._keys[: self._n]
            self._keys = grown
        self._keys[self._n] = key
        self._n += 1
        self._rows.append(entry)
        self._sources.add(entry.source)
        self._texts.add(entry.text)

    def _unit(self, entry: StoredExperience) -> np.ndarray:
        if entry.key_embedding is None:
            raise ValueError(f"entry {entry.id}: key_embedding is missing; use `await store.add([...])` to embed")
        vec = np.asarray(entry.key_embedding, dtype=np.float32)
        if vec.shape != (self.dim,):
            raise ValueError(f"entry {entry.id}: key_embedding has shape {vec.shape}, this store uses {self.dim}")
        norm = float(np.linalg.norm(vec))
        if not np.isfinite(norm) or norm == 0.0:
            raise ValueError(f"entry {entry.id}: key_embedding is zero or not finite")
        return vec if abs(norm - 1.0) <= 1e-4 else vec / np.float32(norm)

    @staticmethod
    def entry_from_record(item: dict[str, Any]) -> StoredExperience:
        """An entry from its episodes.jsonl form (no vector; `embed` computes it)."""
        return StoredExperience(**item)

    def commit(self, episode: int) -> None:
        """Mark the end of one stream episode's additions (a resumed run cuts back to a commit)."""
        self.commits.append([int(episode), self._n])

    # -- reading ------------------------------------------------------------------------------------

    def _scores(self, query: Any, kind: str | None, exclude_instruction: str | None) -> np.ndarray:
        q = np.asarray(query, dtype=np.float32).reshape(-1)
        if q.shape != (self.dim,):
            raise ValueError(f"retrieve: query has {q.size} values, this store uses {self.dim}")
        norm = float(np.linalg.norm(q))
        if norm > 0.0 and abs(norm - 1.0) > 1e-4:
            q = q / np.float32(norm)
        scores = self._keys[: self._n] @ q
        excluded = normalize_instruction(exclude_instruction) if exclude_instruction is not None else None
        for i, row in enumerate(self._rows):
            if (kind is not None and row.kind != kind) or (
                    excluded is not None and normalize_instruction(row.instruction) == excluded):
                scores[i] = -np.inf
        return scores

    def retrieve(self, query: Any, k: int, *, kind: str | None = None,
                 exclude_instruction: str | None = None) -> list[StoredExperience]:
        """Top-k rows (of `kind`, if given) by cosine(query, key embedding), best first; equal scores
        keep insertion order; rows whose instruction equals `exclude_instruction` are skipped."""
        if k <= 0 or self._n == 0:
            return []
        scores = self._scores(query, kind, exclude_instruction)
        order = np.argsort(-scores, kind="stable")
        return [self._rows[i] for i in order[:k] if np.isfinite(scores[i])]

    def retrieve_groups(self, query: Any, k: int, *, kind: str | None = None,
                        exclude_instruction: str | None = None) -> list[list[StoredExperience]]:
        """The k best source episodes (ranked by their best row), each with all its rows of `kind` in
        insertion order: ReasoningBank's "top-1 past task, all its items". Only episodes that have rows
        are ranked (baselines.md §7 pitfall)."""
        if k <= 0 or self._n == 0:
            return []
        scores = self._scores(query, kind, exclude_instruction)
        groups: dict[tuple[str, ...], list[StoredExperience]] = {}
        for i in np.argsort(-scores, kind="stable"):
            if not np.isfinite(scores[i]):
                break
            source = self._rows[i].source
            if source not in groups and len(groups) == k:
                continue
            groups.setdefault(source, [])
        for i, row in enumerate(self._rows):
            if row.source in groups and np.isfinite(scores[i]):
                groups[row.source].append(row)
        return list(groups.values())

    def latest(self, kind: str) -> StoredExperience | None:
        """The most recently added row of `kind` (AWM's current workflow text)."""
        return next((row for row in reversed(self._rows) if row.kind == kind), None)

    def entries(self, kind: str | None = None, *, with_embeddings: bool = False) -> list[StoredExperience]:
        """Rows in insertion order (of one kind, or all), without vectors unless asked for."""
        rows = [(i, r) for i, r in enumerate(self._rows) if kind is None or r.kind == kind]
        if not with_embeddings:
            return [r for _, r in rows]
        return [r.model_copy(update={"key_embedding": self._keys[i].tolist()}) for i, r in rows]

    def counts(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for row in self._rows:
            out[row.kind] = out.get(row.kind, 0) + 1
        return out

    def __len__(self) -> int:
        return self._n

    def __repr__(self) -> str:
        return (f"ExperienceStore({self.counts()}, budget={self.budget} {self.budget_unit}, dedup={self.dedup}, "
                f"embedder={self.embedder_model_id!r})")

    # -- snapshots ----------------------------------------------------------------------------------

    def _empty_like(self) -> ExperienceStore:
        other = ExperienceStore(self._embedder, budget=self.budget, budget_unit=self.budget_unit, dedup=self.dedup)
        other.dim, other.embedder_model_id = self.dim, self.embedder_model_id
        other._keys = np.zeros((0, self.dim), dtype=np.float32)
        return other

    def copy(self) -> ExperienceStore:
        """An independent snapshot (waves): adding to one never changes the other."""
        return self.truncated(self._n, keep_all_commits=True)

    def truncated(self, rows: int, *, keep_all_commits: bool = False) -> ExperienceStore:
        """A copy holding the first `rows` rows (exact: every admission decision depends only on the
        rows before it)."""
        other = self._empty_like()
        for i in range(min(rows, self._n)):
            other._append(self._rows[i], self._keys[i].copy())
        other.commits = [list(c) for c in self.commits if keep_all_commits or c[1] <= rows]
        other.rejected_duplicates, other.rejected_budget = self.rejected_duplicates, self.rejected_budget
        return other

    # -- persistence --------------------------------------------------------------------------------

    def metadata(self) -> dict[str, Any]:
        return {"embedder_model_id": self.embedder_model_id, "dim": self.dim, "budget": self.budget,
                "budget_unit": self.budget_unit, "dedup": self.dedup, "counts": self.counts(),
                "commits": self.commits, "rejected_duplicates": self.rejected_duplicates,
                "rejected_budget": self.rejected_budget}

    def to_dataset(self) -> Any:
        """A `datasets.Dataset`, one row per entry in insertion order, the key vector as float32 list."""
        import pyarrow as pa
        from datasets import Dataset, DatasetInfo, Features, List, Value
        from datasets.fingerprint import generate_random_fingerprint
        from datasets.table import InMemoryTable

        def kind_of(name: str) -> tuple[Any, Any]:
            if name in _INT_FIELDS:
                return Value("int64"), pa.int64()
            if name in _BOOL_FIELDS:
                return Value("bool"), pa.bool_()
            return Value("string"), pa.string()

        cols: dict[str, Any] = {name: kind_of(name)[0] for name in _COLUMNS}
        cols["key_embedding"] = List(Value("float32"), length=self.dim)
        feats = Features(cols)
        arrays = [pa.array([getattr(r, name) for r in self._rows], type=kind_of(name)[1]) for name in _COLUMNS]
        flat = np.ascontiguousarray(self._keys[: self._n], dtype=np.float32).reshape(-1)
        arrays.append(pa.FixedSizeListArray.from_arrays(pa.array(flat, type=pa.float32()), self.dim))
        table = pa.Table.from_arrays(arrays, schema=feats.arrow_schema)
        info = DatasetInfo(description=json.dumps({"format": FORMAT, **self.metadata()}, sort_keys=True),
                           features=feats)
        return Dataset(InMemoryTable(table), info=info, fingerprint=generate_random_fingerprint())

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write to `path` atomically (old or new, never half written); readable by `load_from_disk`."""
        atomic_save_dataset(self.to_dataset(), path)

    @classmethod
    def load(cls, path: Any, embedder: Embedder | None = None, budget: int | None = UNSET, *,
             budget_unit: str | None = None, dedup: str | None = None) -> ExperienceStore:
        """From a folder written by `save` (or a `datasets.Dataset` with the same columns). Settings not
        passed come from the stored metadata; more rows than `budget` keeps the policy's prefix."""
        if not isinstance(path, (str, os.PathLike)):
            return cls.from_dataset(path, embedder, budget=budget, budget_unit=budget_unit, dedup=dedup)
        from datasets import load_from_disk

        if not os.path.isdir(path):
            raise FileNotFoundError(f"no experience store at {path}")
        return cls.from_dataset(load_from_disk(str(path)), embedder, where=str(path), budget=budget,
                                budget_unit=budget_unit, dedup=dedup)

    @classmethod
    def from_dataset(cls, dataset: Any, embedder: Embedder | None = None, *, where: str = "dataset",
                     budget: int | None = UNSET, budget_unit: str | None = None,
                     dedup: str | None = None) -> ExperienceStore:
        from pydantic import ValidationError

        meta = _metadata(dataset)
        settings = resolve_settings(meta, dataset, embedder, where, budget, UNSET)
        store = cls(embedder, budget=settings["budget"], budget_unit=budget_unit or meta.get("budget_unit") or "entries",
                    dedup=dedup or meta.get("dedup") or "none")
        store.dim, store.embedder_model_id = settings["dim"], settings["embedder_model_id"]
        store._keys = np.zeros((0, store.dim), dtype=np.float32)
        commits = meta.get("commits")
        store.commits = [list(map(int, c)) for c in commits] if isinstance(commits, list) else []
        table = dataset.with_format("arrow")[:]
        names = set(table.column_names)
        for required in ("kind", "text", "instruction", "benchmark", "subset", "episode", "task_id"):
            if required not in names:
                raise MemoryDataError(where, required, "column missing")
        rows = []
        for row_no, row in enumerate(table.select([c for c in _COLUMNS if c in names]).to_pylist()):
            try:
                rows.append(StoredExperience.model_validate(row))
            except ValidationError as exc:
                err = exc.errors()[0]
                raise MemoryDataError(f"{where} row {row_no}", ".".join(map(str, err["loc"])) or "row",
                                      err["msg"]) from None
        keys = _key_matrix(table, where, store.dim)
        missing = np.flatnonzero(np.isnan(keys).any(axis=1))
        if missing.size:   # a hand-made dataset without vectors: compute them (loading is synchronous)
            keys[missing] = store.embedder.encode([rows[i].key_text for i in missing])
        for row, key in zip(rows, keys, strict=True):
            if over_budget(store.budget, store.budget_unit, rows=store._n, sources=store._sources,
                           source=row.source):
                break   # the prefix the budget policy would have kept
            store._append(row, store._unit(row.model_copy(update={"key_embedding": key.tolist()})))
        return store



def _metadata(dataset: Any) -> dict[str, Any]:
    try:
        meta = json.loads(dataset.info.description or "")
    except (ValueError, AttributeError):
        return {}
    return meta if isinstance(meta, dict) and meta.get("format") == FORMAT else {}


def _key_matrix(table: Any, where: str, dim: int) -> np.ndarray:
    """The key vectors as float32 (n, dim); NaN rows where a value is null or the column absent."""
    out = np.full((table.num_rows, dim), np.nan, dtype=np.float32)
    if "key_embedding" not in table.column_names:
        return out
    for i, value in enumerate(table.column("key_embedding").to_pylist()):
        if value is None:
            continue
        if len(value) != dim:
            raise MemoryDataError(f"{where} row {i}", "key_embedding", f"{len(value)} values, expected {dim}")
        out[i] = value
    return out
