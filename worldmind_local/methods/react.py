"""ReAct: EmbodiedBench's own planner protocol (EB @ b247936, `planner/vlm_planner.py`), the base that
every other method is compared with (baselines.md §2).

Each planning step sends one fresh user message (EB's `chat_history=False`: earlier model answers are
not shown): the instruction, the current image for a vision planner (or nothing, EB's language-only
mode; EB-Navigation's text description for text planners), and after the first step the action history
with the env's feedback. The system message holds the role, the benchmark's env prior (its actions,
their preconditions, EB's guidelines), the action list and `n_shots` worked examples in EB's format.
The answer is EB's JSON: `visual_state_description` (vision planners only), `reasoning_and_reflection`,
`language_plan`, `executable_plan: [{action_id, action_name}]`. Nothing is kept across episodes.
"""

from __future__ import annotations

from typing import Any, ClassVar

from worldmind_local.agent.driver import Episode
from worldmind_local.agent.plan import (
    MAX_ACTION_NAME_CHARS,
    MAX_LANGUAGE_PLAN_CHARS,
    PlanParseError,
    parse_plan,
)
from worldmind_local.agent.prompting import (
    action_list,
    env_prior,
    format_examples,
    format_history,
    load_template,
    render,
    user_content,
)
from worldmind_local.methods.base import BaseMethod, MethodConfig, Proposal

__all__ = ["ReAct", "ReActConfig", "react_schema", "react_messages"]

MAX_REASONING_CHARS = 1200
MAX_VISUAL_CHARS = 600


class ReActConfig(MethodConfig):
    """EB's planner settings: n_shots 10 (ALFRED/Habitat; 3 on Navigation), T=0, 2048 output tokens."""


def react_schema(n_actions: int, max_plan_actions: int, *, visual: bool) -> dict[str, Any]:
    """EB's output schema (`planner_config/generation_guide.py`), with bounded strings and ids."""
    item = {
        "type": "object",
        "properties": {
            "action_id": {"type": "integer", "minimum": 0, "maximum": max(n_actions - 1, 0)},
            "action_name": {"type": "string", "maxLength": MAX_ACTION_NAME_CHARS},
        },
        "required": ["action_id", "action_name"],
        "additionalProperties": False,
    }
    props: dict[str, Any] = {}
    if visual:
        props["visual_state_description"] = {"type": "string", "maxLength": MAX_VISUAL_CHARS}
    props["reasoning_and_reflection"] = {"type": "string", "maxLength": MAX_REASONING_CHARS}
    props["language_plan"] = {"type": "string", "maxLength": MAX_LANGUAGE_PLAN_CHARS}
    props["executable_plan"] = {"type": "array", "items": item, "maxItems": max_plan_actions}
    return {"type": "object", "properties": props, "required": list(props), "additionalProperties": False}


def _output_format(visual: bool) -> str:
    fields = ['"visual_state_description": str'] if visual else []
    fields += ['"reasoning_and_reflection": str', '"language_plan": str',
               '"executable_plan": [{"action_id": int, "action_name": str}, ...]']
    return "{" + ", ".join(fields) + "}"


def react_messages(ep: Episode, *, examples: str, extra_system: str = "", extra_user: str = "",
                   max_plan_actions: int = 20) -> list[dict[str, Any]]:
    """EB's planner messages for the episode's current state. `extra_system`/`extra_user` are where a
    memory method puts what it retrieved (after the examples / after the instruction)."""
    text, image = ep.planner_view()
    visual = image is not None
    bench = ep.env.benchmark
    system = render(
        load_template("common", "react_system"),
        env_prior=env_prior(bench, max_plan_actions=max_plan_actions),
        max_action_id=len(ep.actions) - 1, action_list=action_list(ep.actions),
        examples=(f"\n# Task execution examples (from other tasks; their ids belong to their own episodes)\n"
                  f"{examples}\n" if examples else ""),
        output_format=_output_format(visual),
    )
    if extra_system:
        system += "\n\n" + extra_system.strip()
    observation = ""
    if text is not None:
        observation = f"\n## What you observe now\n{text.strip() or '(no description available)'}\n"
    if extra_user:
        observation = f"\n{extra_user.strip()}\n" + observation
    describe = "Describe what you see in \"visual_state_description\". " if visual else ""
    history = format_history(ep.trajectory, ep.actions)
    template = "react_user_next" if history else "react_user_first"
    values: dict[str, Any] = {"instruction": ep.task.instruction.strip(), "observation": observation,
                              "describe": describe, "max_action_id": len(ep.actions) - 1}
    if history:
        values["history"] = history
    user = render(load_template("common", template), **values)
    return [{"role": "system", "content": system},
            {"role": "user", "content": user_content(user, [image] if image is not None else [])}]


def eb_examples(ep: Episode, n_shots: int | None) -> str:
    """`n_shots` worked examples in EB's format (no predicted states), never from the evaluated task."""
    n = n_shots if n_shots is not None else getattr(ep.adapter, "default_n_shots", 0)
    make = getattr(ep.adapter, "worked_examples", None)
    if not n or make is None:
        return ""
    return format_examples(make(n, data_dir=ep.ctx.data_dir, exclude=(ep.task.id, ep.task.instruction)),
                           with_predictions=False)


async def ask_planner(ep: Episode, messages: list[dict[str, Any]], config: MethodConfig, *,
                      call_key: str, extra: dict[str, Any] | None = None) -> Proposal:
    """One planner request under EB's schema, parsed with the shared robust parser."""
    visual = ep.planner_view()[1] is not None
    request = ep.calls.request("planner", messages, call_key=call_key, max_tokens=config.planner_max_tokens,
                               json_schema=react_schema(len(ep.actions), config.max_plan_actions, visual=visual))
    result = await ep.calls.ask(request, call_key=call_key)
    try:
        return Proposal(parse_plan(result.text), result, result.text, extra=dict(extra or {}))
    except PlanParseError as exc:
        return Proposal(None, result, result.text, error=str(exc), extra=dict(extra or {}))


def reasoning_of(text: str) -> str:
    """The `reasoning_and_reflection` + `language_plan` of an answer (for trajectory rendering)."""
    try:
        from worldmind_local.agent.plan import extract_first_json_object

        obj = extract_first_json_object(text)
    except PlanParseError:
        return ""
    parts = [obj.get("reasoning_and_reflection"), obj.get("language_plan")]
    return " ".join(p.strip() for p in parts if isinstance(p, str) and p.strip())


class ReAct(BaseMethod):
    name: ClassVar[str] = "react"
    description: ClassVar[str] = "ReAct: EmbodiedBench's own planner (reason, plan, act; no memory)"
    memory_scope: ClassVar[Any] = "episodic"
    config_class: ClassVar[type[MethodConfig]] = ReActConfig

    async def start(self, ep: Episode) -> None:
        ep.state["examples"] = eb_examples(ep, self.config.n_shots)

    async def plan(self, ep: Episode) -> Proposal:
        index = len(ep.record.plans)
        messages = react_messages(ep, examples=ep.state["examples"], max_plan_actions=self.config.max_plan_actions)
        return await ask_planner(ep, messages, self.config, call_key=f"planner:{index}")
