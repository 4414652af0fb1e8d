"""Model calls of one episode: which backend plays a role, reproducible seeds, and token accounting.

Every call's `Sampling.seed` is derived from (run seed, task index, call key), where the call key names
the call's place in the episode ("planner:3", "judge:step7", ...). Keys, not a running counter: the
judge and reflector calls of one plan run concurrently, and a counter would then depend on which
answer came back first. With the same seed, task and model answers, every request is byte-identical,
so a response cache or the replay backend reproduces a run exactly.
"""

from __future__ import annotations

import asyncio
import contextvars
import hashlib
from collections.abc import Awaitable, Mapping, Sequence
from typing import Any

from models.base import ChatBackend, ChatRequest, ChatResult, Role, Sampling, request_key
from worldmind_local.records import CallRecord, EpisodeRecord

__all__ = ["derive_seed", "ROLE_FALLBACK", "backend_for", "has_vision", "ModelCalls"]

# A role without its own backend borrows one: the paper's M plays planner and distiller, the judge
# model validates, reflects and summarises.
ROLE_FALLBACK: dict[str, tuple[str, ...]] = {
    "planner": ("planner",),
    "judge": ("judge", "planner"),
    "reflector": ("reflector", "judge", "planner"),
    "distiller": ("distiller", "planner"),
    "summarizer": ("summarizer", "judge", "planner"),
    "refiner": ("refiner", "judge", "planner"),
    # The baselines' modules run on the backbone (baselines.md): BoN's selector, SimuRA's encoder,
    # policy memory, world model and critic, and the memory methods' judge, extractor and inductor.
    **{role: (role, "planner") for role in ("selector", "encoder", "memory_update", "world_model", "critic",
                                             "memory_judge", "extractor", "inductor")},
}


# Where a call stands in the episode's call tree: calls made one after another get consecutive indices;
# the branches of `ModelCalls.gather` get their own sub-scopes. Sorting by it lists concurrent calls in
# branch order, whatever order they finished in.
_SCOPE: contextvars.ContextVar[tuple[int, ...]] = contextvars.ContextVar("worldmind_call_scope", default=())


def derive_seed(seed: int, task_index: int, call_key: str) -> int:
    """A 31-bit seed, stable across processes and Python versions (no `hash()`)."""
    digest = hashlib.sha256(f"{seed}:{task_index}:{call_key}".encode()).digest()
    return int.from_bytes(digest[:4], "big") & 0x7FFFFFFF


def backend_for(models: Mapping[str, ChatBackend], role: str) -> ChatBackend:
    for candidate in ROLE_FALLBACK.get(role, (role,)):
        if candidate in models:
            return models[candidate]
    raise KeyError(f"no backend for role {role!r} (given: {', '.join(sorted(models)) or 'none'})")


def has_vision(backend: Any) -> bool | None:
    """Whether a backend serves a vision-language model, from its spec; None when nothing says.
    Wrappers (cache, limiter) are looked through via `.inner`."""
    seen = 0
    while backend is not None and seen < 8:
        spec = getattr(backend, "spec", None)
        if spec is not None and getattr(spec, "vision", None) is not None:
            return bool(spec.vision)
        if isinstance(getattr(backend, "vision", None), bool):
            return bool(backend.vision)
        backend = getattr(backend, "inner", None)
        seen += 1
    return None


class ModelCalls:
    """Sends one request per call to the role's backend and books tokens and latency on the record."""

    def __init__(
        self,
        models: Mapping[str, ChatBackend],
        record: EpisodeRecord,
        *,
        seed: int,
        task_index: int,
        temperature: float = 0.0,
    ) -> None:
        self.models = models
        self.record = record
        self.seed = seed
        self.task_index = task_index
        self.temperature = temperature
        self.stats: Any = None  # the method's counters (e.g. WorldMindStats), for the role helpers
        self._next: dict[tuple[int, ...], int] = {}
        self._order: dict[int, tuple[int, ...]] = {}  # id(CallRecord) -> position in the call tree

    def _position(self) -> tuple[int, ...]:
        scope = _SCOPE.get()
        index = self._next.get(scope, 0)
        self._next[scope] = index + 1
        return (*scope, index)

    async def gather(self, *aws: Awaitable[Any]) -> list[Any]:
        """`asyncio.gather` whose branches' calls are recorded in branch order (deterministic records,
        however the concurrent requests finish)."""
        base = self._position()

        async def branch(j: int, aw: Awaitable[Any]) -> Any:
            _SCOPE.set((*base, j))
            return await aw

        return list(await asyncio.gather(*(branch(j, aw) for j, aw in enumerate(aws))))

    def sort_calls(self) -> None:
        """Put the record's calls in call-tree order (the driver does this at the end of the episode)."""
        position = {id(c): self._order.get(id(c), ()) for c in self.record.calls}
        self.record.calls.sort(key=lambda c: position[id(c)])

    def backend(self, role: str) -> ChatBackend:
        return backend_for(self.models, role)

    def request(
        self,
        role: Role,
        messages: Sequence[dict[str, Any]],
        *,
        call_key: str,
        max_tokens: int,
        json_schema: dict[str, Any] | None = None,
        temperature: float | None = None,
        top_p: float = 1.0,
        n: int = 1,
    ) -> ChatRequest:
        sampling = Sampling(
            temperature=self.temperature if temperature is None else temperature,
            max_tokens=max_tokens,
            top_p=top_p,
            n=n,
            seed=derive_seed(self.seed, self.task_index, call_key),
        )
        return ChatRequest(messages=list(messages), sampling=sampling, json_schema=json_schema, role=role)

    async def ask(self, request: ChatRequest, *, call_key: str = "") -> ChatResult:
        """One request; tokens, latency and a CallRecord (with the request's cache key) are booked.

        The CallRecord is placed when the request is sent, not when it returns, so concurrent calls
        (a plan's verifications, SimuRA's clusters) are listed in a deterministic order."""
        backend = self.backend(request.role)
        model_id = getattr(backend, "model_id", "")
        call = CallRecord(key=call_key or f"{request.role}:{len(self.record.calls)}", role=str(request.role),
                          request=request_key(model_id, request), model=model_id, n=request.sampling.n)
        self.record.calls.append(call)
        self._order[id(call)] = self._position()
        results = await backend.complete([request])
        if len(results) != 1:
            raise RuntimeError(f"{request.role} backend returned {len(results)} results for 1 request")
        result = results[0]
        self.record.add_tokens(request.role, result.prompt_tokens, result.completion_tokens, result.latency_s)
        call.prompt_tokens, call.completion_tokens = result.prompt_tokens, result.completion_tokens
        call.latency_s = round(result.latency_s, 6)
        return result
