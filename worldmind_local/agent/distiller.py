"""GoalDistiller: turns a successful trajectory into one reusable workflow (Goal Experience).

The trajectory is shown step by step with EmbodiedBench's task_progress after each step, and every
step that raised the progress is marked, so the model can tell the key actions from the detours. The
answer is a single abstract workflow (objects replaced by roles such as [TARGET_OBJECT]).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from models.base import ChatResult
from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render
from worldmind_local.records import StepRecord

__all__ = ["DISTILLER_SCHEMA", "Distillation", "annotate_trajectory", "parse_workflow", "GoalDistiller"]

DISTILLER_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {"workflow": {"type": "string", "maxLength": 1500}},  # = MAX_WORKFLOW_CHARS
    "required": ["workflow"],
    "additionalProperties": False,
}
_WORKFLOW_KEYS = ("workflow", "success_experience", "goal_experience")
MAX_WORKFLOW_CHARS = 1500


@dataclass(frozen=True, slots=True)
class Distillation:
    workflow: str | None
    unparseable: bool = False
    result: ChatResult | None = field(default=None, compare=False, repr=False)


def annotate_trajectory(steps: Sequence[StepRecord]) -> str:
    """One line per env step: action, feedback, task_progress, and a marker where progress rose."""
    lines, last = [], 0.0
    for i, s in enumerate(st for st in steps if st.env_step):
        line = f"Step {i}: action id {s.action_id}, {s.action_name} | feedback: {s.feedback} | task_progress: {s.progress:.2f}"
        if s.progress > last + 1e-9:
            line += f"  <-- progress increased by {s.progress - last:.2f}"
        last = max(last, s.progress)
        lines.append(line)
    return "\n".join(lines)


def parse_workflow(text: str) -> str | None:
    try:
        obj = extract_first_json_object(text)
    except PlanParseError:
        return None
    value = next((obj[k] for k in _WORKFLOW_KEYS if k in obj), None)
    if not isinstance(value, str) or not value.strip():
        return None
    return " ".join(value.split())[:MAX_WORKFLOW_CHARS]


class GoalDistiller:
    def __init__(self, benchmark: str, calls: ModelCalls, *, max_tokens: int = 512) -> None:
        self.benchmark = benchmark
        self.calls = calls
        self.max_tokens = max_tokens

    async def distill(
        self, *, instruction: str, task_type: str, steps: Sequence[StepRecord], call_key: str
    ) -> Distillation:
        user = render(
            load_template("common", "distiller_user"),
            instruction=instruction.strip(), task_type=task_type or "(unknown)",
            trajectory=annotate_trajectory(steps),
        )
        messages = [
            {"role": "system", "content": load_template(self.benchmark, "distiller").strip()},
            {"role": "user", "content": user},
        ]
        request = self.calls.request(
            "distiller", messages, call_key=call_key, max_tokens=self.max_tokens, json_schema=DISTILLER_SCHEMA
        )
        result = await self.calls.ask(request, call_key=call_key)
        workflow = parse_workflow(result.text)
        record = self.calls.stats
        record.distillations += 1
        record.distillation_tokens.append(result.prompt_tokens + result.completion_tokens)
        record.distiller_unparseable += int(workflow is None)
        return Distillation(workflow, workflow is None, result)
