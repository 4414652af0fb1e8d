"""Response cache: every model answer of a run, keyed by `models.base.request_key`.

`ResponseCache(path)` is one sqlite file (`runs/<id>/cache.sqlite`) in WAL mode, safe to share between
threads and between processes. `CachingBackend(inner, cache)` wraps any backend: hits come from the
file, misses go to the inner backend in one batch and are written before they are returned, so a run
that crashes loses no paid-for answer, and `replay` can later re-run it exactly without the model.

Next to every response the request itself is kept (`requests` table: messages with images as their
sha256, sampling, schema, role; first write wins), so a recorded answer can be read with its question.

The cache is not the source of truth (`episodes.jsonl` is): a damaged file (not a database, or failing
sqlite's `quick_check`) is moved aside as `cache.sqlite.corrupt-<timestamp>` with a warning and the run
goes on with an empty cache. Opened read only (`create=False`: replay, `worldmind show`) it cannot be
replaced, so damage is a `ReplayCacheError`, one line naming the file.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from models.base import BackendError, ChatBackend, ChatRequest, ChatResult, _jsonable_content, request_key

__all__ = ["CACHE_FILENAME", "CachingBackend", "ReplayCacheError", "ResponseCache", "request_record",
           "resolve_cache_path"]

log = logging.getLogger(__name__)

CACHE_FILENAME = "cache.sqlite"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS responses (
    key TEXT PRIMARY KEY,
    model TEXT NOT NULL,
    role TEXT NOT NULL,
    texts TEXT NOT NULL,
    prompt_tokens INTEGER NOT NULL,
    completion_tokens INTEGER NOT NULL,
    latency_s REAL NOT NULL,
    created REAL NOT NULL
)
"""
_REQUESTS_SCHEMA = "CREATE TABLE IF NOT EXISTS requests (key TEXT PRIMARY KEY, request TEXT NOT NULL)"
_DAMAGE_CODES = (11, 26)  # SQLITE_CORRUPT, SQLITE_NOTADB (primary result codes)


class ReplayCacheError(BackendError, ValueError):
    """A response cache opened read only (replay) is damaged: its answers cannot be served."""


class _Damaged(Exception):
    """The file is not a usable sqlite database (the reason is the message)."""


def _is_damage(exc: sqlite3.DatabaseError) -> bool:
    code = getattr(exc, "sqlite_errorcode", None)
    if code is not None:
        return code & 0xFF in _DAMAGE_CODES
    text = str(exc)
    return "not a database" in text or "malformed" in text


def request_record(request: ChatRequest) -> dict[str, Any]:
    """The request as JSON-able data: messages (an image becomes its sha256, size and mode), sampling,
    schema, template options and role."""
    return {
        "messages": [
            {**{k: v for k, v in m.items() if k != "content"}, "content": _jsonable_content(m.get("content"))}
            for m in request.messages
        ],
        "sampling": asdict(request.sampling),
        "json_schema": request.json_schema,
        "chat_template_kwargs": request.chat_template_kwargs,
        "role": request.role,
    }


def resolve_cache_path(path: str | Path) -> Path:
    """A run folder means its `cache.sqlite`; anything else is the file itself."""
    p = Path(path).expanduser()
    return p / CACHE_FILENAME if p.is_dir() else p


class ResponseCache:
    """sqlite store of `ChatResult`s. Results read back carry `cached=True` and their recorded numbers."""

    def __init__(self, path: str | Path, *, create: bool = True) -> None:
        self.path = resolve_cache_path(path)
        self.read_only = not create
        if not create and not self.path.is_file():
            raise FileNotFoundError(f"response cache {self.path} does not exist")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._broken: str | None = None
        try:
            self._db = self._connect()
        except _Damaged as exc:
            if self.read_only:
                raise self._replay_error(str(exc)) from None
            self._move_aside(str(exc))
            self._db = self._connect()

    def _connect(self) -> sqlite3.Connection:
        """Open, set WAL, make the tables, and run sqlite's quick_check; _Damaged if the file is bad."""
        db = sqlite3.connect(self.path, check_same_thread=False, timeout=30.0)
        try:
            db.execute("PRAGMA journal_mode=WAL")
            db.execute("PRAGMA synchronous=NORMAL")
            db.execute(_SCHEMA)
            db.execute(_REQUESTS_SCHEMA)
            db.commit()
            verdict = db.execute("PRAGMA quick_check(1)").fetchone()
        except sqlite3.DatabaseError as exc:
            db.close()
            if _is_damage(exc):
                raise _Damaged(str(exc)) from None
            raise
        if not verdict or verdict[0] != "ok":
            db.close()
            raise _Damaged("quick_check: " + " ".join(str(verdict[0] if verdict else "no answer").split()))
        return db

    def _move_aside(self, reason: str) -> None:
        """Rename the damaged file (and its WAL) to `<name>.corrupt-<timestamp>`; drop its shared memory."""
        stamp = time.strftime("%Y%m%dT%H%M%S")
        aside = self.path.with_name(f"{self.path.name}.corrupt-{stamp}")
        os.replace(self.path, aside)
        wal = self.path.with_name(self.path.name + "-wal")
        if wal.exists():
            os.replace(wal, aside.with_name(aside.name + "-wal"))
        self.path.with_name(self.path.name + "-shm").unlink(missing_ok=True)
        log.warning("response cache %s is damaged (%s): moved aside to %s; continuing with an empty cache "
                    "(answers recorded there will be asked again)", self.path, reason, aside.name)

    def _replay_error(self, reason: str) -> ReplayCacheError:
        return ReplayCacheError(f"{self.path} is damaged ({reason}); its recorded answers cannot be replayed: "
                                "restore the file, or re-record with a live backend and --cache")

    def _failed(self, exc: sqlite3.DatabaseError) -> None:
        """Damage found mid-run: replay cannot go on; a recording run stops using the cache (warned once)."""
        if not _is_damage(exc):
            raise exc
        if self.read_only:
            raise self._replay_error(str(exc)) from None
        if self._broken is None:
            log.warning("response cache %s became unreadable (%s); the run goes on without caching", self.path, exc)
        self._broken = str(exc)

    def get(self, key: str) -> ChatResult | None:
        return self.get_many([key]).get(key)

    def get_many(self, keys: Iterable[str]) -> dict[str, ChatResult]:
        wanted = list(dict.fromkeys(keys))
        found: dict[str, ChatResult] = {}
        if self._broken is not None:
            return found
        with self._lock:
            try:
                for start in range(0, len(wanted), 500):  # stay under sqlite's bound-variable limit
                    chunk = wanted[start : start + 500]
                    marks = ",".join("?" * len(chunk))
                    rows = self._db.execute(
                        "SELECT key, model, texts, prompt_tokens, completion_tokens, latency_s "
                        f"FROM responses WHERE key IN ({marks})",
                        chunk,
                    ).fetchall()
                    for key, model, texts, n_prompt, n_completion, latency in rows:
                        found[key] = ChatResult(
                            texts=json.loads(texts), prompt_tokens=n_prompt, completion_tokens=n_completion,
                            latency_s=latency, cached=True, model=model,
                        )
            except sqlite3.DatabaseError as exc:
                self._failed(exc)
                return {}
        return found

    def put(self, key: str, result: ChatResult, model_id: str, role: str = "",
            request: ChatRequest | None = None) -> None:
        self.put_many([(key, result, model_id, role)], requests={key: request} if request else None)

    def put_many(self, entries: Iterable[tuple[str, ChatResult, str, str]],
                 requests: Mapping[str, ChatRequest] | None = None) -> None:
        """Write results and their requests in one transaction (first write of a key wins: a recorded
        answer is never silently replaced)."""
        now = time.time()
        rows = [
            (key, model_id, role, json.dumps(r.texts, ensure_ascii=False), r.prompt_tokens, r.completion_tokens,
             r.latency_s, now)
            for key, r, model_id, role in entries
        ]
        asked = [(key, json.dumps(request_record(req), ensure_ascii=False, default=str))
                 for key, req in (requests or {}).items()]
        if self._broken is not None:
            return
        with self._lock:
            try:
                self._db.executemany("INSERT OR IGNORE INTO responses VALUES (?, ?, ?, ?, ?, ?, ?, ?)", rows)
                self._db.executemany("INSERT OR IGNORE INTO requests VALUES (?, ?)", asked)
                self._db.commit()
            except sqlite3.DatabaseError as exc:
                self._failed(exc)

    def get_request(self, key: str) -> dict[str, Any] | None:
        """The recorded request of a response key (see `request_record`), or None (an older cache, or
        an answer written without its request)."""
        with self._lock:
            try:
                row = self._db.execute("SELECT request FROM requests WHERE key = ?", (key,)).fetchone()
            except sqlite3.OperationalError:  # a read-only cache made before the requests table
                return None
        return json.loads(row[0]) if row else None

    def keys(self, *, model: str | None = None, role: str | None = None) -> list[str]:
        """Response keys in the order they were recorded, optionally of one model and/or role."""
        query, args = "SELECT key FROM responses WHERE 1=1", []
        for column, value in (("model", model), ("role", role)):
            if value is not None:
                query += f" AND {column} = ?"
                args.append(value)
        with self._lock:
            return [k for (k,) in self._db.execute(query + " ORDER BY rowid", args).fetchall()]

    def models(self) -> dict[str, int]:
        """model id -> number of recorded responses."""
        with self._lock:
            rows = self._db.execute("SELECT model, COUNT(*) FROM responses GROUP BY model").fetchall()
        return {model: count for model, count in rows}

    def __len__(self) -> int:
        with self._lock:
            return int(self._db.execute("SELECT COUNT(*) FROM responses").fetchone()[0])

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and self.get(key) is not None

    def close(self) -> None:
        with self._lock:
            self._db.close()

    def __enter__(self) -> ResponseCache:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class CachingBackend:
    """Serves what the cache has; sends the rest to `inner` in one call and records every answer."""

    def __init__(self, inner: ChatBackend, cache: ResponseCache | str | Path) -> None:
        self.inner = inner
        self.cache = cache if isinstance(cache, ResponseCache) else ResponseCache(cache)
        self.name = inner.name
        self.model_id = inner.model_id
        self.hits = 0
        self.misses = 0

    async def complete(self, requests: Sequence[ChatRequest]) -> list[ChatResult]:
        keys = [request_key(self.model_id, r) for r in requests]
        found = self.cache.get_many(keys)
        missing: dict[str, ChatRequest] = {}
        for key, request in zip(keys, requests, strict=True):
            if key not in found and key not in missing:
                missing[key] = request  # identical requests in one batch are asked once
        if missing:
            answers = await self.inner.complete(list(missing.values()))
            self.cache.put_many(
                [(key, result, self.model_id, request.role)
                 for (key, request), result in zip(missing.items(), answers, strict=True)],
                requests=missing,
            )
            found.update(zip(missing, answers, strict=True))
        self.misses += len(missing)
        self.hits += len(requests) - len(missing)
        results, seen = [], set()
        for key in keys:  # a key asked twice gets its own copy, not a shared object
            results.append(replace(found[key], texts=list(found[key].texts)) if key in seen else found[key])
            seen.add(key)
        return results

    async def aclose(self) -> None:
        await self.inner.aclose()
        self.cache.close()
