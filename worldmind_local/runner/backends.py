"""How streams share backends: one object per model spec, roles mapped onto planner and judge models."""

from __future__ import annotations

import asyncio
from typing import Any

from models.base import ChatRequest, ChatResult

__all__ = ["LimitedBackend", "role_backends", "ROLE_SOURCE"]

# Which of the two models of a stream plays each role. The planner M also distills its own successes
# (paper Sec. 2: "the agent M acts as a task analysis expert"); the judge model validates, reflects
# (the root-cause analyst) and summarises images into abstract states.
ROLE_SOURCE = {
    "planner": "planner",
    "distiller": "planner",
    "judge": "judge",
    "reflector": "judge",
    "summarizer": "judge",
}


class LimitedBackend:
    """Bounds the requests in flight across every backend that shares `limiter` (--max-concurrency)."""

    def __init__(self, inner: Any, limiter: asyncio.Semaphore) -> None:
        self.inner = inner
        self.limiter = limiter
        self.name = inner.name
        self.model_id = inner.model_id

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        async with self.limiter:
            return await self.inner.complete(requests)

    async def aclose(self) -> None:
        await self.inner.aclose()


def role_backends(built: dict[str, Any], planner: str, judge: str) -> tuple[dict[str, Any], dict[str, str]]:
    source = {"planner": planner, "judge": judge}
    models = {role: built[source[src]] for role, src in ROLE_SOURCE.items()}
    ids = {role: getattr(b, "model_id", "") for role, b in models.items()}
    return models, ids
