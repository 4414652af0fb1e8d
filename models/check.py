"""`worldmind models check`: load a model, send planner-style structured requests, measure.

N requests shaped like WorldMind planner calls (an instruction, a numbered action list, the JSON plan
schema) go to the backend in ONE `complete` call, so a batching backend answers them together; one
more request alone gives the batch-1 speed. The report says whether every answer parsed against the
schema and how much batching buys (tokens/s batched vs batch 1).
"""

from __future__ import annotations

import asyncio
import json
import time
from typing import Any

from models.base import ChatBackend, ChatRequest, Sampling

__all__ = ["PLAN_SCHEMA", "check_spec", "planner_requests", "plan_is_valid"]

PLAN_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "language_plan": {"type": "string", "maxLength": 200},
        "executable_plan": {
            "type": "array",
            "minItems": 1,
            "maxItems": 3,
            "items": {
                "type": "object",
                "properties": {
                    "action_id": {"type": "integer", "minimum": 0, "maximum": 11},
                    "action_name": {"type": "string", "maxLength": 40},
                    "predicted_state": {"type": "string", "maxLength": 100},
                },
                "required": ["action_id", "action_name", "predicted_state"],
                "additionalProperties": False,
            },
        },
    },
    "required": ["language_plan", "executable_plan"],
    "additionalProperties": False,
}

_ACTIONS = (
    "find a apple", "pick up the apple", "find a fridge", "open the fridge", "put down the object in hand",
    "close the fridge", "find a sink", "turn on the faucet", "turn off the faucet", "find a countertop",
    "find a mug", "pick up the mug",
)
_TASKS = (
    "Put a washed apple in the fridge.", "Place a cold apple on the countertop.", "Put the mug in the fridge.",
    "Rinse the mug in the sink.", "Put the apple in the sink.", "Chill the mug and put it on the countertop.",
    "Bring the apple to the countertop.", "Open the fridge and put the apple inside.",
)
_SYSTEM = (
    "You control a household robot. Plan the next actions for the task. For every action give its id from "
    "the list, its name, and the state you expect right after it. Reply with JSON only."
)


def planner_requests(n: int, max_tokens: int = 128) -> list[ChatRequest]:
    """N distinct planner-style requests (different tasks) with the plan schema."""
    actions = "\n".join(f"{i}: {name}" for i, name in enumerate(_ACTIONS))
    return [
        ChatRequest(
            messages=[
                {"role": "system", "content": _SYSTEM},
                {"role": "user", "content": f"Task: {_TASKS[i % len(_TASKS)]} (episode {i})\nActions:\n{actions}"},
            ],
            sampling=Sampling(temperature=0.0, max_tokens=max_tokens),
            json_schema=PLAN_SCHEMA,
            role="planner",
        )
        for i in range(n)
    ]


def plan_is_valid(text: str) -> bool:
    """The answer parses as JSON and has the plan's required fields with the right types."""
    try:
        plan = json.loads(text)
    except ValueError:
        return False
    if not isinstance(plan, dict) or not isinstance(plan.get("language_plan"), str):
        return False
    steps = plan.get("executable_plan")
    return isinstance(steps, list) and all(
        isinstance(s, dict) and isinstance(s.get("action_id"), int) and isinstance(s.get("action_name"), str)
        and isinstance(s.get("predicted_state"), str)
        for s in steps
    )


async def _measure(backend: ChatBackend, n: int, max_tokens: int) -> dict[str, Any]:
    await backend.complete(planner_requests(1, max_tokens=4))  # warm-up: first-call kernel set-up
    single = planner_requests(1, max_tokens)
    start = time.perf_counter()
    one = await backend.complete(single)
    t1 = time.perf_counter() - start
    batch = planner_requests(n, max_tokens)
    start = time.perf_counter()
    many = await backend.complete(batch)
    tn = time.perf_counter() - start
    valid = [plan_is_valid(r.text) for r in many]
    return {
        "json_valid_rate": round(sum(valid) / len(valid), 4),
        "tokens_per_s_batch1": round(sum(r.completion_tokens for r in one) / t1, 2),
        "tokens_per_s_batched": round(sum(r.completion_tokens for r in many) / tn, 2),
    }


async def _measure_and_close(backend: ChatBackend, n: int, max_tokens: int) -> dict[str, Any]:
    """One event loop for both: async clients (httpx, vLLM) belong to the loop that made them."""
    try:
        return await _measure(backend, n, max_tokens)
    finally:
        await backend.aclose()


def check_spec(address: str, n: int = 8, max_tokens: int = 192, **options: Any) -> dict[str, Any]:
    """Load the spec's backend, measure, close it. Never raises: a failure is `ok: false` + `error`."""
    from models.specs import load_spec, make_backend

    report: dict[str, Any] = {
        "ok": False, "backend": None, "model": None, "json_valid_rate": None,
        "tokens_per_s_batch1": None, "tokens_per_s_batched": None, "load_s": None,
    }
    try:
        spec = load_spec(address)
        report["backend"], report["model"] = spec.backend, spec.model_id
        start = time.perf_counter()
        backend = make_backend(spec, **options)
        report["load_s"] = round(time.perf_counter() - start, 2)
        report.update(asyncio.run(_measure_and_close(backend, n, max_tokens)))
        report["ok"] = report["json_valid_rate"] == 1.0
    except Exception as exc:  # a check reports, it does not crash
        report["error"] = f"{type(exc).__name__}: {exc}"
    return report
