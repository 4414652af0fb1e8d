"""Whatever a user has as a memory, read the same way: a run, a stream's `memory/`, an export, parquet, the Hub cache.

`--memory-from` and every `worldmind memory` tool take one of:

- a run folder with exactly one stream (`RUN/streams/<id>/memory`), or a stream's `memory/` (a
  `save_to_disk` folder);
- an exported folder (`worldmind memory export`: a Hub dataset repository, `README.md` card + parquet);
- a parquet file, or a folder of parquet files;
- `hub:OWNER/NAME[@REVISION]`: a dataset repository in the local Hugging Face cache (read offline; never
  downloaded here);
- `stream:<id>` (inside `worldmind run`/`transfer` only): another stream of the same run.

Each is read into one `Repository` (an Arrow table in insertion order, the repository settings, the
provenance the source carries) and checked: the partition column (`partition` for the World Knowledge
Repository, `kind` for the baselines' `ExperienceStore`), the required columns, the embedding dimension
and unique ids. A problem is one `MemoryDataError` line naming the file and the field.

What was loaded is identified by `content_sha256`, a hash of the rows and vectors (not of files or
paths), so the same repository has the same hash as a run's `memory/`, as its export, as parquet and in
the Hub cache, and a run that names it by another path is the same run.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from worldmind_local.memory.entries import MemoryDataError

__all__ = [
    "Repository", "MemorySource", "locate", "read_repository", "open_source", "content_sha256",
    "source_key", "load_for_method", "run_provenance", "hub_cache_dir", "parquet_meta", "to_dataset", "describe",
    "CARD_KEY", "PARQUET_META_KEY",
]

CARD_KEY = "worldmind"                       # the card's YAML section with settings and provenance
PARQUET_META_KEY = b"worldmind_local"        # the same, in each parquet file's schema metadata
EMBEDDINGS = ("key_embedding", "text_embedding")
REQUIRED = ("id", "text", "instruction", "benchmark", "subset", "episode", "task_id", "key_embedding")
_FORMATS = {"worldmind_local.wkr/1": "partition", "worldmind_local.store/1": "kind"}
_DATASET_MARKERS = ("dataset_info.json", "dataset_dict.json")


@dataclass
class Repository:
    """A memory as read: rows in insertion order, the settings needed to rebuild it, its provenance."""

    table: Any                      # pyarrow.Table
    meta: dict[str, Any]            # the memory's own settings (format, dim, embedder id, dedup, budget, commits)
    provenance: dict[str, Any]      # where it came from (the card's or the run's facts)
    where: str                      # what errors name
    files: list[str] = field(default_factory=list)   # the data file of each row (errors name it)

    @property
    def partition_column(self) -> str:
        return "partition" if "partition" in self.table.column_names else "kind"

    @property
    def memory_format(self) -> str:
        """`worldmind_local.wkr/1` (World Knowledge Repository) or `worldmind_local.store/1` (a baseline's)."""
        return "worldmind_local.wkr/1" if self.partition_column == "partition" else "worldmind_local.store/1"

    @property
    def dim(self) -> int:
        return int(self.meta.get("dim") or self.table.schema.field("key_embedding").type.list_size)

    def counts(self) -> dict[str, int]:
        column = self.table.column(self.partition_column).to_pylist()
        return {name: column.count(name) for name in dict.fromkeys(column)}

    def rows(self, with_embeddings: bool = False) -> list[dict[str, Any]]:
        names = [c for c in self.table.column_names if with_embeddings or c not in EMBEDDINGS]
        return self.table.select(names).to_pylist()

    @property
    def sha256(self) -> str:
        return content_sha256(self.table)


@dataclass(frozen=True)
class MemorySource:
    """What `--memory-from` resolved to, as recorded in manifest/results `memory_sources`."""

    value: str          # as typed
    kind: str           # run | stream | memory | export | parquet | hub
    location: str       # absolute path (the Hub cache snapshot folder for hub:)
    sha256: str
    provenance: dict[str, Any]
    counts: dict[str, int]
    entries: int

    def facts(self) -> dict[str, Any]:
        return {"value": self.value, "kind": self.kind, "path": self.location, "sha256": self.sha256,
                "entries": self.entries, "counts": self.counts, "provenance": self.provenance}

    @property
    def label(self) -> str:
        """`model/benchmark#hash8`: the results table's `memory_from` cell."""
        planner = self.provenance.get("planner")
        model = (planner.get("model_id") or planner.get("spec")) if isinstance(planner, dict) else planner
        model = model or "+".join(self.provenance.get("entry_models") or []) or "?"
        bench = self.provenance.get("benchmark") or "+".join(self.provenance.get("benchmarks") or []) or "?"
        return f"{model}/{bench}#{self.sha256[:8]}"


# -- where a value points ---------------------------------------------------------------------------

def hub_cache_dir() -> Path:
    """The Hub cache, read from the environment now (huggingface_hub reads it once, at import)."""
    if os.environ.get("HF_HUB_CACHE"):
        return Path(os.environ["HF_HUB_CACHE"]).expanduser()
    home = os.environ.get("HF_HOME") or os.path.join(os.environ.get("XDG_CACHE_HOME", "~/.cache"), "huggingface")
    return Path(home).expanduser() / "hub"


def _hub_snapshot(value: str) -> Path:
    """`hub:OWNER/NAME[@REV]` -> the cached snapshot folder (offline: nothing is downloaded)."""
    from huggingface_hub import snapshot_download
    from huggingface_hub.errors import HfHubHTTPError, LocalEntryNotFoundError

    spec = value[len("hub:"):]
    repo_id, _, revision = spec.partition("@")
    if repo_id.count("/") > 1 or not repo_id.strip("/"):
        raise ValueError(f"{value}: expected hub:OWNER/NAME[@REVISION]")
    try:
        folder = snapshot_download(repo_id, repo_type="dataset", revision=revision or None,
                                   local_files_only=True, cache_dir=hub_cache_dir())
    except (LocalEntryNotFoundError, HfHubHTTPError, OSError, ValueError) as exc:
        raise FileNotFoundError(
            f"{value}: dataset {repo_id}{'@' + revision if revision else ''} is not in the local Hub cache "
            f"{hub_cache_dir()} ({type(exc).__name__}); this suite never downloads, so put it there first "
            "(e.g. `hf download --repo-type dataset ...` on a machine with the Hub)") from None
    return Path(folder)


def _stream_memories(run: Path) -> list[Path]:
    return sorted(p for p in run.glob("streams/*/memory") if p.is_dir())


def _is_export(folder: Path) -> bool:
    return (folder / "README.md").is_file() and any(folder.rglob("*.parquet"))


def locate(value: str) -> tuple[str, Path]:
    """(kind, absolute path) for a `--memory-from` value, reading only names and markers (preflight).

    Errors are one line saying what was found and what would be right."""
    if value.startswith("hub:"):
        return "hub", _hub_snapshot(value)
    path = Path(value).expanduser()
    if not path.exists():
        raise FileNotFoundError(f"--memory-from {value}: no such folder or file")
    path = path.resolve()
    if path.is_file():
        if path.suffix != ".parquet":
            raise ValueError(f"--memory-from {value} is a file but not a .parquet file; give a repository "
                             "folder, an export, a parquet file or hub:OWNER/NAME")
        with path.open("rb") as f:
            if f.read(4) != b"PAR1":
                raise ValueError(f"--memory-from {value} is a file that is not parquet (no PAR1 magic)")
        return "parquet", path
    if any((path / marker).is_file() for marker in _DATASET_MARKERS):
        return "memory", path
    inside = _stream_memories(path)
    if inside and (path / "manifest.json").is_file():
        if len(inside) == 1:
            return "run", inside[0]
        shown = ", ".join(p.parent.name for p in inside)
        raise ValueError(f"--memory-from {value} is a run folder with {len(inside)} streams; pick one: "
                         f"{value}/streams/<id>/memory with <id> one of {shown}")
    if inside:
        shown = ", ".join(str(p) for p in inside[:3]) + (", ..." if len(inside) > 3 else "")
        raise ValueError(f"--memory-from {value} is a run folder without manifest.json; pick one of its "
                         f"memories: {shown}")
    if _is_export(path):
        return "export", path
    if any(path.glob("*.parquet")):
        return "parquet", path
    raise ValueError(f"--memory-from {value} does not look like a repository (no dataset_info.json, no "
                     "README.md with parquet, no *.parquet); give a run, a memory/ folder, an export or parquet")


# -- reading ----------------------------------------------------------------------------------------

def _meta_from_json(text: Any) -> dict[str, Any]:
    try:
        meta = json.loads(text or "")
    except (TypeError, ValueError):
        return {}
    return meta if isinstance(meta, dict) and meta.get("format") in _FORMATS else {}


def _read_saved(folder: Path) -> tuple[Any, dict[str, Any]]:
    from worldmind_local.memory.storage import as_single_dataset, load_saved_dataset

    dataset = as_single_dataset(load_saved_dataset(folder))
    return dataset.with_format("arrow")[:], _meta_from_json(dataset.info.description)


def parquet_meta(schema: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """(repository settings, provenance) stored in a parquet file's schema metadata by `export`."""
    raw = (schema.metadata or {}).get(PARQUET_META_KEY)
    try:
        whole = json.loads(raw.decode("utf-8")) if raw else {}
    except (UnicodeDecodeError, ValueError):
        whole = {}
    if not isinstance(whole, dict):
        return {}, {}
    provenance = whole.get("provenance")
    return _meta_from_json(json.dumps(whole.get("repository"))), provenance if isinstance(provenance, dict) else {}


def _read_parquet_file(path: Path) -> tuple[Any, dict[str, Any]]:
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        reason = " ".join(str(exc).split())[:160]
        raise MemoryDataError(str(path), "<file>", f"unreadable parquet ({reason})") from None
    return table, parquet_meta(table.schema)[0]


def _card(folder: Path) -> dict[str, Any]:
    """The card's YAML metadata, parsed with huggingface_hub's card tools ({} without a card)."""
    from huggingface_hub import DatasetCard

    readme = folder / "README.md"
    if not readme.is_file():
        return {}
    try:
        return DatasetCard.load(readme).data.to_dict()
    except Exception as exc:  # noqa: BLE001 - yaml and card errors alike mean "unreadable card"
        raise MemoryDataError(str(readme), "<yaml>", f"unreadable card ({' '.join(str(exc).split())[:160]})") from None


def _default_data_files(folder: Path, card: dict[str, Any]) -> list[Path]:
    """The default config's data files (an export repeats rows in per-partition configs; read them once)."""
    configs = card.get("configs") or []
    chosen = next((c for c in configs if c.get("default")), None) or next(
        (c for c in configs if c.get("config_name") == "default"), None)
    patterns: list[str] = []
    if chosen is not None:
        files = chosen.get("data_files")
        for item in files if isinstance(files, list) else [files]:
            if isinstance(item, dict):
                paths = item.get("path")
                patterns += paths if isinstance(paths, list) else [paths]
            elif isinstance(item, str):
                patterns.append(item)
    found = sorted({p for pattern in patterns if pattern for p in folder.glob(pattern) if p.is_file()})
    return found or sorted(folder.glob("*.parquet")) or sorted(folder.glob("data/*.parquet"))


def _read_parquet_files(files: list[Path], where: str) -> tuple[Any, dict[str, Any], list[str]]:
    import pyarrow as pa

    if not files:
        raise MemoryDataError(where, "<data>", "no parquet data files")
    tables, meta, owners = [], {}, []
    for path in files:
        table, file_meta = _read_parquet_file(path)
        _check_columns(table, str(path), file_meta)
        tables.append(_normalise(table, str(path), file_meta))
        meta = meta or file_meta
        owners += [str(path)] * table.num_rows
    try:
        table = pa.concat_tables(tables, promote_options="permissive")
    except pa.ArrowException as exc:
        raise MemoryDataError(where, "<schema>", f"data files disagree ({' '.join(str(exc).split())[:160]})") from None
    return table, meta, owners


def read_repository(kind: str, path: Path, *, value: str = "") -> Repository:
    """Read and check the repository at `path` (a `locate` result)."""
    where = str(path)
    if kind in ("memory", "run", "stream"):
        table, meta = _read_saved(path)
        _check_columns(table, where, meta)
        table = _normalise(table, where, meta)
        repo = Repository(table, meta, run_provenance(path), where, [where] * table.num_rows)
    elif kind in ("export", "hub"):
        card = _card(path)
        files = _default_data_files(path, card)
        table, file_meta, owners = _read_parquet_files(files, where)
        section = card.get(CARD_KEY) if isinstance(card.get(CARD_KEY), dict) else {}
        meta = _meta_from_json(json.dumps(section.get("repository"))) or file_meta
        repo = Repository(table, meta, {k: v for k, v in section.items() if k != "repository"}, where, owners)
    else:
        files = [path] if path.is_file() else sorted(path.glob("*.parquet"))
        table, meta, owners = _read_parquet_files(files, where)
        import pyarrow.parquet as pq

        provenance = parquet_meta(pq.read_schema(files[0]))[1]
        repo = Repository(table, meta, provenance, where, owners)
    _check_repository(repo)
    return repo


def open_source(value: str) -> tuple[MemorySource, Repository]:
    """Resolve, read and describe a `--memory-from` value (or a `worldmind memory` tool's input)."""
    kind, path = locate(value)
    repo = read_repository(kind, path, value=value)
    return describe(value, kind, path, repo), repo


def describe(value: str, kind: str, path: Path, repo: Repository) -> MemorySource:
    provenance = dict(repo.provenance)
    benchmarks = sorted(set(repo.table.column("benchmark").to_pylist()))
    provenance.setdefault("benchmarks", benchmarks)
    return MemorySource(value=value, kind=kind, location=str(path), sha256=repo.sha256, provenance=provenance,
                        counts=repo.counts(), entries=repo.table.num_rows)


# -- checks -----------------------------------------------------------------------------------------

def _check_columns(table: Any, where: str, meta: dict[str, Any]) -> None:
    names = set(table.column_names)
    if "partition" not in names and "kind" not in names:
        raise MemoryDataError(where, "partition", "column missing (a World Knowledge Repository has "
                                                  "'partition', a baseline's experience store 'kind')")
    for required in REQUIRED:
        if required not in names:
            raise MemoryDataError(where, required, "column missing")
    for name in EMBEDDINGS:
        if name in names and not _is_list(table.schema.field(name).type):
            raise MemoryDataError(where, name, f"expected a list of floats, found {table.schema.field(name).type}")


def _is_list(kind: Any) -> bool:
    import pyarrow as pa

    return pa.types.is_list(kind) or pa.types.is_fixed_size_list(kind) or pa.types.is_large_list(kind)


def _normalise(table: Any, where: str, meta: dict[str, Any]) -> Any:
    """Embedding columns as fixed-size float32 lists of the stated dimension (errors name the row)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    dim = meta.get("dim")
    for name in EMBEDDINGS:
        if name not in table.column_names:
            continue
        column = table.column(name).combine_chunks()
        lengths = pc.list_value_length(column).to_numpy(zero_copy_only=False)
        valid = np.asarray(column.is_valid().to_numpy(zero_copy_only=False), dtype=bool)
        if dim is None and valid.any():
            dim = int(lengths[valid][0])
        if dim is None:
            continue
        bad = np.flatnonzero(valid & (np.nan_to_num(lengths.astype(float), nan=-1) != dim))
        if bad.size:
            raise MemoryDataError(f"{where} row {int(bad[0])}", name,
                                  f"{int(lengths[bad[0]])} values, expected {dim}"
                                  + (" (the repository's stated dim)" if meta.get("dim") else ""))
        target = pa.list_(pa.float32(), int(dim))
        if column.type != target:
            column = column.cast(target)
        table = table.set_column(table.column_names.index(name), name, column)
    return table


def _check_repository(repo: Repository) -> None:
    """Unique ids; a stated dimension that matches the vectors."""
    ids = repo.table.column("id").to_pylist()
    seen: dict[str, int] = {}
    for row, entry_id in enumerate(ids):
        if entry_id in seen:
            raise MemoryDataError(repo.files[row] if repo.files else repo.where, "id",
                                  f"duplicate id {entry_id!r} (rows {seen[entry_id]} and {row})")
        seen[entry_id] = row
    stated = repo.meta.get("dim")
    actual = repo.table.schema.field("key_embedding").type
    size = getattr(actual, "list_size", None)
    if stated and size and int(stated) != int(size):
        raise MemoryDataError(repo.where, "key_embedding", f"{size}-dim vectors, the repository says dim {stated}")


# -- identity ---------------------------------------------------------------------------------------

def content_sha256(table: Any) -> str:
    """A hash of the rows in order (every column, vectors as float32 bytes): the same repository has the
    same hash whatever form it is stored in."""
    h = hashlib.sha256()
    names = sorted(table.column_names)
    h.update(json.dumps(names).encode())
    plain = [n for n in names if n not in EMBEDDINGS]
    for row in table.select(plain).to_pylist():
        h.update(json.dumps(row, sort_keys=True, ensure_ascii=False, default=str).encode() + b"\n")
    for name in (n for n in names if n in EMBEDDINGS):
        column = table.column(name).combine_chunks()
        h.update(name.encode())
        if column.null_count == 0:
            flat = np.asarray(column.flatten().to_numpy(zero_copy_only=False), dtype="<f4")
            h.update(np.ascontiguousarray(flat).tobytes())
            continue
        for value in column.to_pylist():
            h.update(b"\x00" if value is None else np.asarray(value, dtype="<f4").tobytes())
    return h.hexdigest()


def _signature(path: Path) -> tuple[Any, ...]:
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    return tuple((str(p), p.stat().st_size, p.stat().st_mtime_ns) for p in files)


@functools.lru_cache(maxsize=256)
def _cached_key(kind: str, path: str, signature: tuple[Any, ...]) -> str:
    return read_repository(kind, Path(path)).sha256


def source_key(value: str) -> str | None:
    """The content hash a run is identified by, or None when the value cannot be read now (the run's
    preflight then says why in one line). `stream:<id>` has no content yet: its key is the reference."""
    if value.startswith("stream:"):
        return None
    try:
        kind, path = locate(value)
        return _cached_key(kind, str(path), _signature(path))
    except (OSError, ValueError):
        return None


# -- provenance of a run's stream -------------------------------------------------------------------

def _json(path: Path) -> dict[str, Any]:
    try:
        value = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def _stream_spec(manifest: dict[str, Any], results: dict[str, Any], stream_id: str) -> dict[str, Any]:
    for stream in results.get("streams") or []:
        if stream.get("stream_id") == stream_id:
            return stream
    for raw in (manifest.get("config") or {}).get("streams") or []:
        try:
            from worldmind_local.runner.config import StreamSpec

            spec = StreamSpec(**raw)
        except Exception:  # noqa: BLE001 - a spec of another version: skip it
            continue
        if spec.stream_id == stream_id:
            return spec.model_dump(mode="json")
    return {}


def _model(manifest: dict[str, Any], address: str | None) -> dict[str, Any]:
    facts = (manifest.get("models") or {}).get(address or "") or {}
    files = facts.get("files") or {}
    digest = hashlib.sha256(json.dumps(sorted(files.items())).encode()).hexdigest() if files else None
    return {"spec": address, "model_id": facts.get("model_id"), "backend": facts.get("backend"),
            "weights_sha256": digest, "weights": files or None, "note": facts.get("note")}


def run_provenance(memory: Path) -> dict[str, Any]:
    """Facts about a stream's memory from its run folder (`RUN/streams/<id>/memory`); {} elsewhere."""
    if memory.parent.parent.name != "streams":
        return {}
    run, stream_id = memory.parent.parent.parent, memory.parent.name
    manifest = _json(run / "manifest.json")
    if not manifest:
        return {}
    spec = _stream_spec(manifest, _json(run / "results.json"), stream_id)
    data = (manifest.get("data") or {}).get(stream_id) or {}
    planner = spec.get("planner")
    judge = spec.get("judge") or planner
    return {
        "benchmark": spec.get("benchmark"), "subset": spec.get("subset"), "method": spec.get("method"),
        "planner": _model(manifest, planner), "judge": _model(manifest, judge),
        "run_id": manifest.get("run_id"), "stream_id": stream_id, "git_sha": manifest.get("git_sha"),
        "suite": data.get("suite"), "data_sha256": data.get("tasks_sha256"), "episodes": data.get("episodes"),
        "memory_from": spec.get("memory_from"), "memory_sha256": spec.get("memory_sha256"),
    }


# -- loading for a method ---------------------------------------------------------------------------

def to_dataset(repo: Repository) -> Any:
    """The repository as a `datasets.Dataset` with its settings in `info.description` (what `save` writes)."""
    from datasets import Dataset, DatasetInfo, Features
    from datasets.fingerprint import generate_random_fingerprint
    from datasets.table import InMemoryTable

    table = repo.table.replace_schema_metadata(None)
    meta = {**repo.meta, "format": repo.meta.get("format") or repo.memory_format, "dim": repo.dim}
    info = DatasetInfo(description=json.dumps(meta, sort_keys=True), features=Features.from_arrow_schema(table.schema))
    return Dataset(InMemoryTable(table), info=info, fingerprint=generate_random_fingerprint())


def _check_fits(method: Any, repo: Repository, value: str, embedder: Any, budget: int | None) -> None:
    """A method's memory kind and the source's agree (one line, not a KeyError deep in a loader)."""
    from worldmind_local.memory.repository import WorldKnowledgeRepository

    probe = method.new_memory(embedder, budget)
    if probe is None:
        return
    wants = "partition" if isinstance(probe, WorldKnowledgeRepository) else "kind"
    if wants != repo.partition_column:
        have = "a World Knowledge Repository" if repo.partition_column == "partition" else "a baseline's store"
        need = "a World Knowledge Repository" if wants == "partition" else "a baseline's experience store"
        raise MemoryDataError(repo.where, wants, f"{value} holds {have} (column {repo.partition_column!r}); "
                                                 f"method {method.name} needs {need}")


def load_for_method(value: str, method: Any, embedder: Any, budget: int | None, *,
                    kind: str | None = None, path: Path | None = None) -> tuple[Any, MemorySource]:
    """The method's memory seeded from `value`, and what was loaded. A `save_to_disk` folder is handed
    to the method as is; any other form is written to a temporary `save_to_disk` folder first, so every
    method keeps one loader."""
    if kind is None or path is None:
        kind, path = locate(value)
    repo = read_repository(kind, path, value=value)
    source = describe(value, kind, path, repo)
    _check_fits(method, repo, value, embedder, budget)
    if kind in ("memory", "run", "stream"):
        return method.load_memory(str(path), embedder, budget), source
    scratch = Path(tempfile.mkdtemp(prefix="worldmind-memory-"))
    try:
        to_dataset(repo).save_to_disk(str(scratch / "memory"))
        return method.load_memory(str(scratch / "memory"), embedder, budget), source
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
