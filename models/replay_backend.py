"""`replay`: answers only from a recorded response cache, so a run repeats exactly without the model.

A run made with `--cache` records every answer in `cache.sqlite` keyed by (model id, messages,
sampling, schema, template options). Replaying with the same model id returns the very same texts,
token counts and latencies, with no weights, no GPU and no network. A request that was never recorded
is an error naming its key and the model, never a silent fallback to some other answer. A damaged
cache file is a `ReplayCacheError` (one line naming the file), never moved aside: here it is the only
copy of the answers.

Ways to get one:
- `make_backend("replay:hf:smollm2-135m-instruct", cache="runs/x")`: the model id of that spec;
- `make_backend("replay:HuggingFaceTB/SmolLM2-135M-Instruct", cache="runs/x/cache.sqlite")`: a raw id;
- `make_backend("replay", cache="runs/x")`: the only model the cache holds (an error if several);
- `ReplayBackend(spec_or_none, cache_path=..., model_id=...)` directly.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from models.base import BackendError, ChatRequest, ChatResult, ModelNotFoundError, request_key
from models.cache import ReplayCacheError, ResponseCache, resolve_cache_path
from models.specs import ModelSpec

REPLAY_CACHE_ENV = "WORLDMIND_REPLAY_CACHE"  # where `worldmind run --planner replay:...` finds the cache

__all__ = ["ReplayBackend", "ReplayCacheError"]


class ReplayBackend:
    """A `ChatBackend` backed by a `ResponseCache` file (read only: it never writes)."""

    name = "replay"

    def __init__(
        self,
        spec: ModelSpec | None = None,
        *,
        cache_path: str | Path | None = None,
        cache: str | Path | None = None,
        model_id: str | None = None,
    ) -> None:
        path = (cache_path or cache or (spec.options.get("cache") if spec else None)
                or os.environ.get(REPLAY_CACHE_ENV))
        if not path:
            raise ValueError(
                "replay backend: give the recorded cache (cache_path=runs/<id> or .../cache.sqlite, or set "
                f"{REPLAY_CACHE_ENV}=runs/<id> for `worldmind run --planner replay:<spec>`)"
            )
        self.path = resolve_cache_path(path)
        if not self.path.is_file():
            raise ModelNotFoundError(f"replay backend: response cache {self.path} does not exist")
        self.cache = ResponseCache(self.path, create=False)
        self.spec = spec
        self.model_id = self._pick_model(model_id or (spec.model_id if spec else None))
        self.served = 0

    def _pick_model(self, wanted: str | None) -> str:
        recorded = self.cache.models()
        if wanted:
            if wanted not in recorded:
                known = ", ".join(f"{m} ({n})" for m, n in sorted(recorded.items())) or "none"
                raise BackendError(f"replay backend: {self.path} has no responses of model {wanted!r}; it has: {known}")
            return wanted
        if len(recorded) != 1:
            known = ", ".join(sorted(recorded)) or "none"
            raise BackendError(f"replay backend: name the model to replay (model_id=...); {self.path} holds: {known}")
        return next(iter(recorded))

    async def complete(self, requests: Sequence[ChatRequest]) -> list[ChatResult]:
        keys = [request_key(self.model_id, r) for r in requests]
        found = self.cache.get_many(keys)
        for index, key in enumerate(keys):
            if key not in found:
                raise BackendError(
                    f"replay backend: no recorded response for request {index} (role {requests[index].role}, "
                    f"key {key}) of model {self.model_id} in {self.path}; record it with a live backend and --cache"
                )
        self.served += len(keys)
        return [replace(found[key], texts=list(found[key].texts)) for key in keys]

    async def aclose(self) -> None:
        self.cache.close()


def make_replay(address: str, **options: Any) -> ReplayBackend:
    """`replay`, `replay:<spec address>` or `replay:<model id>` (see the module docstring)."""
    from models.specs import load_spec

    target = address.partition(":")[2]
    spec = None
    if ":" in target:  # replay:backend:name -> that spec's model id (else a raw model id with a colon)
        try:
            spec = load_spec(target)
        except KeyError:
            spec = None
    model_id = options.pop("model_id", None) or (spec.model_id if spec else target or None)
    return ReplayBackend(None, model_id=model_id, **options)
