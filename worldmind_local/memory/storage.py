"""The World Knowledge Repository as a Hugging Face dataset, written atomically.

A repository is one `datasets.Dataset`, one row per entry in insertion order, with every provenance
field as a column and both embeddings as fixed-length float32 lists, so anyone can open it with plain
`datasets.load_from_disk(path)` (or push it to the Hub) and see where each experience came from. The
repository's settings (embedder model id, dimension, dedup threshold, budget, counts) travel inside the
dataset, as JSON in `info.description`.

Saving never leaves a half-written folder: the dataset is written to a temporary folder beside the
target, then swapped in with one atomic `renameat2(RENAME_EXCHANGE)` on Linux (a rename when the target
does not exist yet), and the old copy is deleted afterwards. A crash at any point leaves either the old
or the new repository at `path`. The saved folder gets the modes a plain `mkdir` / `open` would give
it (0755 / 0644 under the usual umask 022), not the 0700 of the temporary folder it was written in.

`load_saved_dataset` is `datasets.load_from_disk` for repositories we did not write: a damaged arrow or
JSON file becomes a MemoryDataError naming that file, not a pyarrow error naming nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import json
import os
import shutil
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from worldmind_local.memory.embedder import DEFAULT_DIM, DEFAULT_MODEL_ID
from worldmind_local.memory.entries import EMBEDDING_FIELDS, PARTITIONS, ExperienceEntry, MemoryDataError

__all__ = [
    "FORMAT", "UNSET", "features", "build_dataset", "read_dataset", "read_metadata", "as_single_dataset",
    "resolve_settings", "atomic_save_dataset", "load_saved_dataset",
]

FORMAT = "worldmind_local.wkr/1"
_INT = ("episode", "step")
_COLUMNS = tuple(f for f in ExperienceEntry.model_fields if f not in EMBEDDING_FIELDS)
UNSET: Any = object()   # "not passed": take the setting stored with the dataset


def features(dim: int) -> Any:
    """The dataset schema: provenance columns in the entry's field order, then the two embeddings."""
    from datasets import Features, List, Value

    cols: dict[str, Any] = {}
    for name in _COLUMNS:
        cols[name] = Value("int64") if name in _INT else Value("string")
    for name in EMBEDDING_FIELDS:
        cols[name] = List(Value("float32"), length=dim)
    return Features(cols)


def build_dataset(entries: list[ExperienceEntry], keys: np.ndarray, texts: np.ndarray,
                  metadata: dict[str, Any]) -> Any:
    """Rows in insertion order; `keys`/`texts` are the (n, dim) matrices aligned with `entries`.

    Built as an Arrow table directly: `Dataset.from_dict` walks every float of every embedding in
    Python (seconds per thousand entries), which would dominate a save after every episode.
    """
    import pyarrow as pa
    from datasets import Dataset, DatasetInfo
    from datasets.fingerprint import generate_random_fingerprint
    from datasets.table import InMemoryTable

    dim = int(metadata["dim"])
    feats = features(dim)
    arrays = [
        pa.array([getattr(e, name) for e in entries], type=pa.int64() if name in _INT else pa.string())
        for name in _COLUMNS
    ]
    for matrix in (keys, texts):
        flat = np.ascontiguousarray(matrix, dtype=np.float32).reshape(-1)
        if flat.size != len(entries) * dim:
            raise ValueError(f"embedding matrix of {flat.size} values for {len(entries)} entries x {dim} dims")
        arrays.append(pa.FixedSizeListArray.from_arrays(pa.array(flat, type=pa.float32()), dim))
    table = pa.Table.from_arrays(arrays, schema=feats.arrow_schema)
    info = DatasetInfo(description=json.dumps({"format": FORMAT, **metadata}, sort_keys=True), features=feats)
    # a fresh random fingerprint: hashing the whole table (the default) costs more than building it
    return Dataset(InMemoryTable(table), info=info, fingerprint=generate_random_fingerprint())


def read_metadata(dataset: Any) -> dict[str, Any]:
    """The repository settings stored with a dataset ({} for a dataset someone else made)."""
    try:
        meta = json.loads(dataset.info.description or "")
    except (ValueError, AttributeError):
        return {}
    return meta if isinstance(meta, dict) and meta.get("format") == FORMAT else {}


def as_single_dataset(dataset: Any) -> Any:
    """A Dataset as is; a DatasetDict as its splits concatenated in order (a split named after a
    partition supplies the `partition` column if it lacks one)."""
    from datasets import Dataset, DatasetDict, concatenate_datasets

    if isinstance(dataset, Dataset):
        return dataset
    if not isinstance(dataset, DatasetDict):
        raise TypeError(f"expected a path, a datasets.Dataset or a DatasetDict, got {type(dataset).__name__}")
    parts = []
    for name, split in dataset.items():
        if "partition" not in split.column_names and name in PARTITIONS:
            split = split.add_column("partition", [name] * len(split))
        parts.append(split)
    if not parts:
        raise MemoryDataError("DatasetDict", "splits", "no splits")
    merged = concatenate_datasets(parts)
    first = next(iter(dataset.values()))
    merged.info.description = first.info.description
    return merged


def resolve_settings(meta: dict[str, Any], dataset: Any, embedder: Any, where: str, budget: Any,
                     dedup_threshold: Any) -> dict[str, Any]:
    """Dimension, embedder id, budget and threshold for a loaded repository; refuses mixed embedders."""
    feature = dataset.features.get("key_embedding")
    stored_dim = meta.get("dim") or (getattr(feature, "length", -1) if feature is not None else -1)
    stored_dim = int(stored_dim) if stored_dim and int(stored_dim) > 0 else None
    stored_id = meta.get("embedder_model_id")
    if embedder is not None:
        if stored_dim is not None and stored_dim != embedder.dim:
            raise MemoryDataError(where, "key_embedding",
                                  f"{stored_dim}-dim embeddings, but the embedder makes {embedder.dim}")
        if stored_id and stored_id != embedder.model_id:
            raise MemoryDataError(where, "embedder_model_id",
                                  f"embeddings from {stored_id}, but the embedder is {embedder.model_id}")
    return {
        "dim": embedder.dim if embedder is not None else stored_dim or DEFAULT_DIM,
        "embedder_model_id": embedder.model_id if embedder is not None else stored_id or DEFAULT_MODEL_ID,
        "budget": meta.get("budget") if budget is UNSET else budget,
        "dedup_threshold": meta.get("dedup_threshold", 0.95) if dedup_threshold is UNSET else dedup_threshold,
    }


def read_dataset(dataset: Any, where: str, dim: int) -> tuple[list[ExperienceEntry], np.ndarray, np.ndarray]:
    """Entries (without embedding lists) and the two (n, dim) embedding matrices, in row order.

    A null or absent embedding becomes a NaN row for the caller to fill in. Errors name `where`, the
    row and the field.
    """
    from pydantic import ValidationError

    table = dataset.with_format("arrow")[:]   # respects an indices mapping (after select/shuffle)
    names = set(table.column_names)
    for required in ("partition", "text", "instruction", "benchmark", "subset", "episode", "task_id"):
        if required not in names:
            raise MemoryDataError(where, required, "column missing")
    plain = table.select([c for c in _COLUMNS if c in names]).to_pylist()
    entries: list[ExperienceEntry] = []
    for row_no, row in enumerate(plain):
        try:
            entries.append(ExperienceEntry.model_validate(row))
        except ValidationError as exc:
            err = exc.errors()[0]
            field = ".".join(str(p) for p in err["loc"]) or "row"
            raise MemoryDataError(f"{where} row {row_no}", field, err["msg"]) from None
    keys, texts = (_matrix(table, name, where, dim) for name in EMBEDDING_FIELDS)
    return entries, keys, texts


def _matrix(table: Any, name: str, where: str, dim: int) -> np.ndarray:
    """One embedding column as float32 (n, dim); NaN rows where the value is null or the column absent."""
    import pyarrow.compute as pc

    out = np.full((table.num_rows, dim), np.nan, dtype=np.float32)
    if name not in table.column_names or table.num_rows == 0:
        return out
    column = table.column(name).combine_chunks()
    valid = np.asarray(column.is_valid().to_numpy(zero_copy_only=False), dtype=bool)
    if not valid.any():
        return out
    present = column.filter(valid)
    lengths = np.asarray(pc.list_value_length(present).to_numpy(zero_copy_only=False))
    if (bad := np.flatnonzero(lengths != dim)).size:
        row = int(np.flatnonzero(valid)[bad[0]])
        raise MemoryDataError(f"{where} row {row}", name, f"{lengths[bad[0]]} values, expected {dim}")
    values = np.asarray(present.flatten().to_numpy(zero_copy_only=False), dtype=np.float32)
    out[valid] = values.reshape(-1, dim)
    return out


# -- atomic save ------------------------------------------------------------------------------------

_bars_lock = threading.Lock()
_bars_state = {"users": 0, "were_disabled": False}


@contextlib.contextmanager
def _quiet_datasets() -> Iterator[None]:
    """No "Saving the dataset" bar per episode; safe when several streams save from worker threads."""
    from datasets.utils import are_progress_bars_disabled, disable_progress_bars, enable_progress_bars

    with _bars_lock:
        if _bars_state["users"] == 0:
            _bars_state["were_disabled"] = are_progress_bars_disabled()
            disable_progress_bars()
        _bars_state["users"] += 1
    try:
        yield
    finally:
        with _bars_lock:
            _bars_state["users"] -= 1
            if _bars_state["users"] == 0 and not _bars_state["were_disabled"]:
                enable_progress_bars()


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux renameat2 RENAME_EXCHANGE); False where unsupported."""
    try:
        renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return False
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    at_fdcwd, rename_exchange = -100, 2
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


def _fsync_dir(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_tree(folder: Path) -> None:
    """Flush the files and the folder, so a power cut after the swap cannot leave empty files."""
    for item in folder.iterdir():
        if item.is_file():
            with item.open("rb") as f:
                os.fsync(f.fileno())
    _fsync_dir(folder)


def _umask() -> int:
    """The process umask, read without changing it (os.umask would race with saving threads)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return 0o022


def _plain_modes(folder: Path) -> None:
    """Folders 0777 & ~umask and files 0666 & ~umask, as mkdir/open would make them (mkdtemp gives 0700)."""
    mask = _umask()
    for root, dirs, files in os.walk(folder):
        os.chmod(root, 0o777 & ~mask)
        for name in files:
            os.chmod(os.path.join(root, name), 0o666 & ~mask)
        for name in dirs:
            os.chmod(os.path.join(root, name), 0o777 & ~mask)


def _damaged_file(folder: Path) -> tuple[Path, str] | None:
    """The first arrow or JSON file of a saved dataset that cannot be read, with the reason."""
    import pyarrow as pa

    for item in sorted(folder.rglob("*")):
        try:
            if item.suffix == ".json":
                json.loads(item.read_text(encoding="utf-8"))
            elif item.suffix == ".arrow":
                with pa.memory_map(str(item)) as source:
                    pa.ipc.open_stream(source).read_all().validate(full=True)
        except (OSError, ValueError, pa.ArrowException) as exc:
            return item, " ".join(str(exc).split())[:200] or type(exc).__name__
    return None


def load_saved_dataset(path: str | os.PathLike[str]) -> Any:
    """`datasets.load_from_disk(path)`, with every data file checked first: a corrupt arrow file or a
    broken `dataset_info.json` is a MemoryDataError naming the file."""
    from datasets import load_from_disk

    folder = Path(path)
    if not folder.is_dir():
        raise FileNotFoundError(f"no saved dataset at {folder}")
    damaged = _damaged_file(folder)
    if damaged is not None:
        raise MemoryDataError(str(damaged[0]), "<file>", f"unreadable ({damaged[1]})")
    try:
        return load_from_disk(str(folder))
    except FileNotFoundError:
        raise
    except Exception as exc:  # noqa: BLE001 - datasets raises many kinds; all mean the same to the user
        reason = " ".join(str(exc).split())[:200]
        raise MemoryDataError(str(folder), "<folder>", f"not a saved dataset ({type(exc).__name__}: {reason})") from None


def _looks_like_dataset(path: Path) -> bool:
    return (path / "dataset_info.json").exists() or (path / "dataset_dict.json").exists() or not any(
        path.iterdir())


def atomic_save_dataset(dataset: Any, path: str | os.PathLike[str]) -> None:
    """`dataset.save_to_disk(path)`, but all-or-nothing: `path` is never half written."""
    target = Path(path)
    if target.exists() and not (target.is_dir() and _looks_like_dataset(target)):
        raise FileExistsError(f"{target} exists and is not a saved dataset; refusing to replace it")
    target.parent.mkdir(parents=True, exist_ok=True)
    for stale in [*target.parent.glob(f".{target.name}.tmp-*"), *target.parent.glob(f".{target.name}.old-*")]:
        shutil.rmtree(stale, ignore_errors=True)   # left by a process killed mid-save
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
    try:
        with _quiet_datasets():
            # an empty dataset saved with the default sharding has no data file and cannot be loaded back
            dataset.save_to_disk(str(tmp), num_shards=1 if len(dataset) == 0 else None)
        _plain_modes(tmp)
        _fsync_tree(tmp)
        if not target.exists():
            os.rename(tmp, target)
        elif not _exchange(tmp, target):
            # no atomic exchange here: move the old copy aside (a brief window without `path`)
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
            os.rename(target, old)
            os.rename(tmp, target)
            shutil.rmtree(old, ignore_errors=True)
        _fsync_dir(target.parent)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)   # after an exchange this holds the old copy

