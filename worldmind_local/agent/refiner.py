"""Experience refiner (official code only; not in the paper): merges the retrieved experience into one
briefing and proposes an initial plan before the planner is called.

The authors' code enables it in all three configs (`enable_experience_refine: true`) and calls it on
every planner call; the paper never mentions it. It is an option here (`refine`), off by default, so
the default follows the paper. Its output replaces the raw retrieved entries in the planner's prompt.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from models.base import ChatResult
from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import format_experience, load_template

__all__ = ["REFINER_SCHEMA", "Refinement", "parse_refinement", "ExperienceRefiner"]

REFINER_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "merged_experience": {"type": "string", "maxLength": 2000},
        "initial_plan": {"type": "string", "maxLength": 1000},
    },
    "required": ["merged_experience", "initial_plan"],
    "additionalProperties": False,
}


@dataclass(frozen=True, slots=True)
class Refinement:
    text: str                 # the block the planner sees
    unparseable: bool = False
    result: ChatResult | None = field(default=None, compare=False, repr=False)


def parse_refinement(text: str, fallback: str) -> tuple[str, bool]:
    """(planner block, unparseable). An unusable answer falls back to the raw retrieved entries."""
    try:
        obj = extract_first_json_object(text)
    except PlanParseError:
        return fallback, True
    merged, plan = obj.get("merged_experience"), obj.get("initial_plan")
    if not isinstance(merged, str) or not merged.strip():
        return fallback, True
    block = merged.strip()
    if isinstance(plan, str) and plan.strip():
        block += f"\n\nSuggested initial plan: {plan.strip()}"
    return block, False


class ExperienceRefiner:
    def __init__(self, calls: ModelCalls, *, max_tokens: int = 768) -> None:
        self.calls = calls
        self.max_tokens = max_tokens

    async def refine(self, *, instruction: str, goal: Sequence[Any], process: Sequence[Any],
                     call_key: str) -> Refinement:
        raw = format_experience(goal, process)
        user = f"## Task\n{instruction.strip()}\n\n## Retrieved knowledge\n{raw}"
        messages = [{"role": "system", "content": load_template("common", "refiner").strip()},
                    {"role": "user", "content": user}]
        request = self.calls.request("refiner", messages, call_key=call_key, max_tokens=self.max_tokens,
                                     json_schema=REFINER_SCHEMA)
        result = await self.calls.ask(request, call_key=call_key)
        text, unparseable = parse_refinement(result.text, raw)
        return Refinement(text, unparseable, result)
