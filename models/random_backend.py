"""`random`: a model-free backend whose answers are a pure function of the request.

It answers a request with a JSON-schema instance (or a short sentence when no schema is given) drawn from
an RNG seeded by the request's cache key, so the same request always gets the same answer, on any
machine. It exists to exercise and measure the harness itself (runner, resume, equivalence of streams)
without a model; it is not a planner and its success rate means nothing.
"""

from __future__ import annotations

import asyncio
import random
import time
from typing import Any

from models.base import ChatRequest, ChatResult, request_key

__all__ = ["RandomBackend", "schema_instance"]

_WORDS = ("the", "object", "is", "in", "hand", "cabinet", "open", "closed", "robot", "at", "counter",
          "apple", "sink", "visible", "first", "then", "place", "find", "navigate", "before")


def _text(rng: random.Random, n_words: int) -> str:
    return " ".join(rng.choice(_WORDS) for _ in range(n_words))


def schema_instance(schema: dict[str, Any], rng: random.Random, depth: int = 0) -> Any:
    """A value valid under the common JSON-schema subset used for structured output."""
    if "const" in schema:
        return schema["const"]
    if "enum" in schema:
        return rng.choice(schema["enum"])
    for key in ("anyOf", "oneOf"):
        if key in schema:
            return schema_instance(rng.choice(schema[key]), rng, depth + 1)
    typ = schema.get("type", "object" if "properties" in schema else "string")
    if isinstance(typ, list):
        typ = rng.choice([t for t in typ if t != "null"] or ["null"])
    if typ == "object":
        props = schema.get("properties", {})
        return {k: schema_instance(v, rng, depth + 1) for k, v in props.items()}
    if typ == "array":
        lo = int(schema.get("minItems", 0))
        hi = int(schema.get("maxItems", lo + 3))
        n = rng.randint(lo, min(hi, lo + 3)) if depth < 4 else lo
        return [schema_instance(schema.get("items", {}), rng, depth + 1) for _ in range(n)]
    if typ == "integer":
        lo = int(schema.get("minimum", 0))
        hi = int(schema.get("maximum", lo + 40))
        return rng.randint(lo, hi)
    if typ == "number":
        return round(rng.uniform(float(schema.get("minimum", 0)), float(schema.get("maximum", 1))), 3)
    if typ == "boolean":
        return rng.random() < 0.5
    if typ == "null":
        return None
    max_len = int(schema.get("maxLength", 200))
    return _text(rng, rng.randint(3, 12))[:max_len]


class RandomBackend:
    name = "random"

    def __init__(self, spec: Any = None, *, latency_s: float = 0.0, **_: Any) -> None:
        self.spec = spec
        self.model_id = getattr(spec, "model_id", "seeded-random")
        self.latency_s = float(getattr(spec, "options", {}).get("latency_s", latency_s)) if spec else latency_s
        self.calls = 0

    def _answer(self, req: ChatRequest) -> ChatResult:
        import json

        key = request_key(self.model_id, req)
        texts = []
        for i in range(req.sampling.n):
            rng = random.Random(f"{key}:{i}")
            if req.json_schema is not None:
                texts.append(json.dumps(schema_instance(req.json_schema, rng)))
            else:
                texts.append(_text(rng, 12))
        prompt_tokens = sum(len(str(m.get("content", "")).split()) for m in req.messages)
        return ChatResult(texts=texts, prompt_tokens=prompt_tokens,
                          completion_tokens=sum(len(t.split()) for t in texts),
                          latency_s=self.latency_s, model=self.model_id)

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        self.calls += 1
        t0 = time.perf_counter()
        if self.latency_s:
            await asyncio.sleep(self.latency_s)
        results = [self._answer(r) for r in requests]
        for r in results:
            r.latency_s = time.perf_counter() - t0
        return results

    async def aclose(self) -> None:
        return None
