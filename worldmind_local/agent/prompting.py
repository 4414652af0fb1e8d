"""Prompt templates (files under `worldmind_local/prompts/`) and the planner's messages.

Templates are Markdown files read with importlib.resources; `{{name}}` marks a slot. Rendering fails
loudly on a slot without a value or a value without a slot, so a template and its caller cannot drift
apart silently. Per benchmark there is one system prompt per role (planner, judge, reflector,
distiller, summarizer); the user-message layouts are shared (`prompts/common/`).

The planner's system message holds the environment prior, the numbered action list, the guidelines
and the output format; its user message holds the instruction, the retrieved Goal and Process
Experience, the step history with EmbodiedBench's feedback, and the current observation (text, plus
the image as a part when the env gives one and the planner is a vision-language model).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from functools import lru_cache
from importlib import resources
from typing import Any

from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.records import StepRecord

__all__ = [
    "PROMPT_BENCHMARKS",
    "ROLE_TEMPLATES",
    "TemplateError",
    "load_template",
    "render",
    "action_list",
    "format_history",
    "format_experience",
    "planner_messages",
    "user_content",
]

PROMPT_BENCHMARKS = ("eb_alfred", "eb_habitat", "eb_navigation")
ROLE_TEMPLATES = ("planner", "judge", "reflector", "distiller", "summarizer")
_SLOT = re.compile(r"\{\{\s*([a-z_][a-z0-9_]*)\s*\}\}")


class TemplateError(KeyError):
    def __str__(self) -> str:
        return str(self.args[0]) if self.args else "template error"


@lru_cache(maxsize=64)
def load_template(folder: str, name: str) -> str:
    """`prompts/<folder>/<name>.md`. `folder` is a benchmark name or "common"."""
    if folder != "common" and folder not in PROMPT_BENCHMARKS:
        raise TemplateError(f"no prompts for benchmark {folder!r}; known: {', '.join(PROMPT_BENCHMARKS)}")
    path = resources.files("worldmind_local.prompts").joinpath(folder, f"{name}.md")
    if not path.is_file():
        raise TemplateError(f"prompt template prompts/{folder}/{name}.md does not exist")
    return path.read_text(encoding="utf-8").strip() + "\n"


def render(template: str, **values: Any) -> str:
    slots = set(_SLOT.findall(template))
    missing = slots - values.keys()
    extra = values.keys() - slots
    if missing or extra:
        raise TemplateError(f"template slots {sorted(slots)}: missing {sorted(missing)}, unused {sorted(extra)}")
    return _SLOT.sub(lambda m: str(values[m.group(1)]), template).strip()


def action_list(actions: Sequence[str]) -> str:
    return "\n".join(f"action id {i}: {name}" for i, name in enumerate(actions))


def format_history(steps: Sequence[StepRecord], actions: Sequence[str]) -> str:
    """EmbodiedBench's history lines, one per env step (unusable outputs never reach the history)."""
    lines = [
        f"Step {i}, action id {s.action_id}, {s.action_name}, env feedback: {s.feedback}"
        for i, s in enumerate(st for st in steps if st.env_step)
    ]
    return "\n".join(lines)


def format_experience(goal: Sequence[Any], process: Sequence[Any]) -> str:
    """The retrieved entries under their headings; a kind with nothing retrieved is left out."""
    parts = []
    if goal:
        items = "\n".join(f"{i}. {e.text}" for i, e in enumerate(goal, 1))
        parts.append(render(load_template("common", "experience_goal"), items=items))
    if process:
        items = "\n".join(f"{i}. {e.text}" for i, e in enumerate(process, 1))
        parts.append(render(load_template("common", "experience_process"), items=items))
    return "\n\n".join(parts)


def user_content(text: str, images: Sequence[Any] = ()) -> str | list[dict[str, Any]]:
    """A plain string, or image parts followed by the text when there are images."""
    if not images:
        return text
    return [*({"type": "image", "image": img} for img in images), {"type": "text", "text": text}]


def planner_messages(
    benchmark: str,
    *,
    actions: Sequence[str],
    instruction: str,
    observation: str,
    history: Sequence[StepRecord],
    goal_experience: Sequence[Any] = (),
    process_experience: Sequence[Any] = (),
    max_plan_actions: int = 20,
    image: Any | None = None,
) -> list[dict[str, Any]]:
    system = render(
        load_template(benchmark, "planner"),
        max_action_id=len(actions) - 1,
        action_list=action_list(actions),
        max_plan_actions=max_plan_actions,
        skip_string=SKIP_STRING,
    )
    history_text = format_history(history, actions)
    user = render(
        load_template("common", "planner_user"),
        instruction=instruction.strip(),
        experience=format_experience(goal_experience, process_experience) or "(no stored experience yet)",
        history=history_text or "(no actions taken yet)",
        observation=observation.strip() or "(no description available)",
        max_action_id=len(actions) - 1,
        skip_string=SKIP_STRING,
    )
    return [
        {"role": "system", "content": system},
        {"role": "user", "content": user_content(user, [image] if image is not None else [])},
    ]
