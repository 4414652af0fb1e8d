"""StateAbstractor (the paper's M_abs): the abstract states s-bar before and after an action.

By default the abstract state is the env's own `Observation.text` (the twins render it from their
symbolic state; a real simulator wrapper from metadata). With `abstract_with="vlm"` and an env that
gives images, a summarizer model looks at the before and after images instead, which is how the paper
abstracts a real simulator. Without images the VLM mode falls back to the text, and says so in
`AbstractState.source`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from models.base import ChatResult
from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render, user_content
from worldmind_local.env import Observation

__all__ = ["SUMMARIZER_SCHEMA", "AbstractState", "StateAbstractor", "observation_image", "parse_summary"]

SUMMARIZER_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {"state_before": {"type": "string"}, "state_after": {"type": "string"}},
    "required": ["state_before", "state_after"],
    "additionalProperties": False,
}


def observation_image(obs: Observation) -> Any | None:
    """The observation's image; an env may hand over a zero-argument function to render lazily."""
    image = getattr(obs, "image", None)
    return image() if callable(image) else image


@dataclass(slots=True)
class AbstractState:
    before: str
    after: str
    source: Literal["text", "vlm"]
    result: ChatResult | None = field(default=None, repr=False)


def _state_field(obj: dict[str, Any], key: str, fallback: str) -> str:
    value = obj.get(key)
    return value.strip() or fallback if isinstance(value, str) else fallback


def parse_summary(text: str, before_text: str, after_text: str) -> tuple[str, str, bool]:
    """(state before, state after, parsed as JSON). Total: a missing or non-string field falls back to
    the env's own text, and free text is taken as the description of the after-image."""
    try:
        obj = extract_first_json_object(text)
    except PlanParseError:
        free = text.strip() if isinstance(text, str) else ""
        return before_text, free or after_text, False
    return _state_field(obj, "state_before", before_text), _state_field(obj, "state_after", after_text), True


class StateAbstractor:
    def __init__(
        self, benchmark: str, calls: ModelCalls, *, mode: Literal["text", "vlm"] = "text", max_tokens: int = 384
    ) -> None:
        if mode not in ("text", "vlm"):
            raise ValueError(f"abstract_with must be 'text' or 'vlm', not {mode!r}")
        self.benchmark = benchmark
        self.calls = calls
        self.mode = mode
        self.max_tokens = max_tokens

    async def abstract(
        self, before: Observation, after: Observation, action_name: str, *, call_key: str
    ) -> AbstractState:
        if self.mode == "vlm":
            images = (observation_image(before), observation_image(after))
            if all(img is not None for img in images):
                return await self._summarize(before, after, action_name, images, call_key)
        return AbstractState(before.text, after.text, "text")

    async def _summarize(
        self, before: Observation, after: Observation, action_name: str, images: tuple[Any, Any], call_key: str
    ) -> AbstractState:
        user = render(load_template("common", "summarizer_user"), action=action_name)
        messages = [
            {"role": "system", "content": load_template(self.benchmark, "summarizer").strip()},
            {"role": "user", "content": user_content(user, images)},
        ]
        request = self.calls.request(
            "summarizer", messages, call_key=call_key, max_tokens=self.max_tokens, json_schema=SUMMARIZER_SCHEMA
        )
        result = await self.calls.ask(request, call_key=call_key)
        self.calls.stats.summarizer_calls += 1
        state_before, state_after, _parsed = parse_summary(result.text, before.text, after.text)
        return AbstractState(state_before, state_after, "vlm", result)
