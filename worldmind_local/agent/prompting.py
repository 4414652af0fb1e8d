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
    "env_prior",
    "render",
    "action_list",
    "format_history",
    "format_experience",
    "planner_messages",
    "format_examples",
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


@lru_cache(maxsize=16)
def _env_prior_template(benchmark: str) -> str:
    if benchmark not in PROMPT_BENCHMARKS:
        raise TemplateError(f"no env prior for benchmark {benchmark!r}; known: {', '.join(PROMPT_BENCHMARKS)}")
    path = resources.files(f"benchmarks.{benchmark}.prompts").joinpath("env_prior.md")
    return path.read_text(encoding="utf-8").strip() + "\n"


def env_prior(benchmark: str, *, max_plan_actions: int) -> str:
    """The benchmark's own description of its actions and planning guidelines
    (`benchmarks/<benchmark>/prompts/env_prior.md`), shared by every method's planner prompt."""
    return render(_env_prior_template(benchmark), max_plan_actions=max_plan_actions)


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


def format_examples(examples: Sequence[Any], *, with_predictions: bool = True) -> str:
    """Worked examples (`env.WorkedExample`) as the planner's output format: WorldMind's, with a
    predicted state per action, or EB's, without."""
    import json

    blocks = []
    for i, ex in enumerate(examples, 1):
        plan = []
        for a in ex.actions:
            item: dict[str, Any] = {"action_id": a.action_id, "action_name": a.action_name}
            if with_predictions:
                item["predicted_state"] = a.predicted_state
            plan.append(item)
        answer = json.dumps({"language_plan": ex.language_plan, "executable_plan": plan}, ensure_ascii=False)
        feedback = "\n".join(f"  {a.action_name} -> {a.feedback}" for a in ex.actions)
        blocks.append(f"## Example {i}\nHuman instruction: {ex.instruction}\nOutput: {answer}\n"
                      f"Env feedback after each action:\n{feedback}")
    return "\n\n".join(blocks)


def planner_messages(
    benchmark: str,
    *,
    actions: Sequence[str],
    instruction: str,
    history: Sequence[StepRecord],
    observation: str | None = None,
    experience: str = "",
    examples: str = "",
    max_plan_actions: int = 20,
    image: Any | None = None,
) -> list[dict[str, Any]]:
    """The planner's two messages. `observation` None (EB's language-only mode) leaves the state
    section out entirely; `experience` and `examples` are pre-rendered blocks ("" leaves them out)."""
    system = render(
        load_template(benchmark, "planner"),
        env_prior=env_prior(benchmark, max_plan_actions=max_plan_actions),
        max_action_id=len(actions) - 1,
        action_list=action_list(actions),
        skip_string=SKIP_STRING,
    )
    if examples:
        system += "\n\n# Worked examples (from other tasks; their action ids belong to their own episodes)\n" + examples
    history_text = format_history(history, actions)
    sections = [f"## Human instruction\n{instruction.strip()}"]
    if experience:
        sections.append(f"## Knowledge from your World Knowledge Repository\n{experience}")
    sections.append(f"## What you have done so far in this episode\n{history_text or '(no actions taken yet)'}")
    if observation is not None:
        sections.append(f"## What you observe now\n{observation.strip() or '(no description available)'}")
    elif image is not None:
        sections.append("## What you observe now\nThe image shows your current view.")
    user = render(
        load_template("common", "planner_user"),
        sections="\n\n".join(sections),
        max_action_id=len(actions) - 1,
        skip_string=SKIP_STRING,
    )
    return [
        {"role": "system", "content": system},
        {"role": "user", "content": user_content(user, [image] if image is not None else [])},
    ]
