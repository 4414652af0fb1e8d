"""Response cache: every model answer of a run, keyed by `models.base.request_key`.

`ResponseCache(path)` is one sqlite file (`runs/<id>/cache.sqlite`) in WAL mode, safe to share between
threads and between processes. `CachingBackend(inner, cache)` wraps any backend: hits come from the
file, misses go to the inner backend in one batch and are written before they are returned, so a run
that crashes loses no paid-for answer, and `replay` can later re-run it exactly without the model.
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections.abc import Iterable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from models.base import ChatBackend, ChatRequest, ChatResult, request_key

__all__ = ["CACHE_FILENAME", "CachingBackend", "ResponseCache", "resolve_cache_path"]

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


def resolve_cache_path(path: str | Path) -> Path:
    """A run folder means its `cache.sqlite`; anything else is the file itself."""
    p = Path(path).expanduser()
    return p / CACHE_FILENAME if p.is_dir() else p


class ResponseCache:
    """sqlite store of `ChatResult`s. Results read back carry `cached=True` and their recorded numbers."""

    def __init__(self, path: str | Path, *, create: bool = True) -> None:
        self.path = resolve_cache_path(path)
        if not create and not self.path.is_file():
            raise FileNotFoundError(f"response cache {self.path} does not exist")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(self.path, check_same_thread=False, timeout=30.0)
        with self._lock:
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.execute(_SCHEMA)
            self._db.commit()

    def get(self, key: str) -> ChatResult | None:
        return self.get_many([key]).get(key)

    def get_many(self, keys: Iterable[str]) -> dict[str, ChatResult]:
        wanted = list(dict.fromkeys(keys))
        found: dict[str, ChatResult] = {}
        with self._lock:
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
        return found

    def put(self, key: str, result: ChatResult, model_id: str, role: str = "") -> None:
        self.put_many([(key, result, model_id, role)])

    def put_many(self, entries: Iterable[tuple[str, ChatResult, str, str]]) -> None:
        """Write results (first write of a key wins: a recorded answer is never silently replaced)."""
        now = time.time()
        rows = [
            (key, model_id, role, json.dumps(r.texts, ensure_ascii=False), r.prompt_tokens, r.completion_tokens,
             r.latency_s, now)
            for key, r, model_id, role in entries
        ]
        with self._lock:
            self._db.executemany("INSERT OR IGNORE INTO responses VALUES (?, ?, ?, ?, ?, ?, ?, ?)", rows)
            self._db.commit()

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
                (key, result, self.model_id, request.role)
                for (key, request), result in zip(missing.items(), answers, strict=True)
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
