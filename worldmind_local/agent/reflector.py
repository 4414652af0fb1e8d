"""Reflector: the root-cause analyst that turns a judged contradiction into Process Experience.

Given the history up to the failed prediction, the action, the state before it, the prediction, the
actual state, EmbodiedBench's feedback and the judge's reason, it answers a JSON list of short
corrective rules (a precondition, an object location, a workflow). Each rule becomes one Process
Experience entry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from models.base import ChatResult
from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.jsonparse import extract_json_list
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render

__all__ = ["reflector_schema", "Reflection", "parse_rules", "Reflector", "MAX_RULE_CHARS"]

# A bound for constrained decoding only (so a looping model still closes its JSON), far above the
# official examples (7 of 9 are over 300 characters); parsing never cuts a rule. The real bound is the
# reflector's token budget.
MAX_RULE_CHARS = 2000
_RULE_KEYS = ("rules", "experience_entry", "experience_entries")


def reflector_schema(max_rules: int | None) -> dict[str, Any]:
    rules: dict[str, Any] = {"type": "array", "items": {"type": "string", "maxLength": MAX_RULE_CHARS}, "minItems": 1}
    if max_rules is not None:
        rules["maxItems"] = max_rules
    return {"type": "object", "properties": {"rules": rules}, "required": ["rules"], "additionalProperties": False}


@dataclass(frozen=True, slots=True)
class Reflection:
    rules: tuple[str, ...]
    unparseable: bool = False
    result: ChatResult | None = field(default=None, compare=False, repr=False)


def _bare_list(text: str) -> list[Any] | None:
    """A bare JSON list (first `[` to last `]`), or None; total and bounded like every role's parse."""
    try:
        return extract_json_list(text)
    except PlanParseError:
        return None


def parse_rules(text: str, max_rules: int | None = None) -> tuple[tuple[str, ...], bool]:
    """(rules, unparseable). Accepts `{"rules": [...]}`, the paper's `{"experience_entry": [...]}`, or a
    bare list. Rules are whitespace-normalised and de-duplicated, never cut; `max_rules` (None: no
    cap) keeps the first ones."""
    raw: Any = None
    try:
        obj = extract_first_json_object(text)
        raw = next((obj[k] for k in _RULE_KEYS if k in obj), None)
        if isinstance(raw, str):
            raw = [raw]
    except PlanParseError:
        raw = _bare_list(text or "")
    if not isinstance(raw, list):
        return (), True
    rules: list[str] = []
    for item in raw:
        rule = " ".join(item.split()) if isinstance(item, str) else ""
        if rule and rule not in rules:
            rules.append(rule)
    return tuple(rules if max_rules is None else rules[:max_rules]), not rules


class Reflector:
    def __init__(self, benchmark: str, calls: ModelCalls, *, max_tokens: int = 1024,
                 max_rules: int | None = None) -> None:
        self.benchmark = benchmark
        self.calls = calls
        self.max_tokens = max_tokens
        self.max_rules = max_rules

    async def reflect(
        self,
        *,
        instruction: str,
        history: str,
        action: str,
        state_before: str,
        predicted: str,
        actual: str,
        feedback: str,
        judge_reason: str,
        call_key: str,
    ) -> Reflection:
        user = render(
            load_template("common", "reflector_user"),
            instruction=instruction.strip(), history=history or "(this was the first action)", action=action,
            state_before=state_before.strip(), predicted=predicted.strip(), actual=actual.strip(),
            feedback=feedback.strip(), judge_reason=judge_reason.strip() or "(no reason given)",
            how_many=(f"at most {self.max_rules} corrective rules" if self.max_rules is not None
                      else "your corrective rules (one per distinct cause)"),
        )
        messages = [
            {"role": "system", "content": load_template(self.benchmark, "reflector").strip()},
            {"role": "user", "content": user},
        ]
        request = self.calls.request(
            "reflector", messages, call_key=call_key, max_tokens=self.max_tokens,
            json_schema=reflector_schema(self.max_rules),
        )
        result = await self.calls.ask(request, call_key=call_key)
        rules, unparseable = parse_rules(result.text, self.max_rules)
        record = self.calls.stats
        record.reflections += 1
        record.reflection_tokens.append(result.prompt_tokens + result.completion_tokens)
        record.reflector_unparseable += int(unparseable)
        return Reflection(rules, unparseable, result)
