"""Reflector: the root-cause analyst that turns a judged contradiction into Process Experience.

Given the history up to the failed prediction, the action, the state before it, the prediction, the
actual state, EmbodiedBench's feedback and the judge's reason, it answers a JSON list of short
corrective rules (a precondition, an object location, a workflow). Each rule becomes one Process
Experience entry.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from models.base import ChatResult
from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render

__all__ = ["reflector_schema", "Reflection", "parse_rules", "Reflector", "MAX_RULE_CHARS"]

MAX_RULE_CHARS = 300
_RULE_KEYS = ("rules", "experience_entry", "experience_entries")


def reflector_schema(max_rules: int) -> dict[str, Any]:
    return {
        "type": "object",
        "properties": {"rules": {"type": "array", "items": {"type": "string", "maxLength": MAX_RULE_CHARS}, "minItems": 1, "maxItems": max_rules}},
        "required": ["rules"],
        "additionalProperties": False,
    }


@dataclass(frozen=True, slots=True)
class Reflection:
    rules: tuple[str, ...]
    unparseable: bool = False
    result: ChatResult | None = field(default=None, compare=False, repr=False)


def _bare_list(text: str) -> list[Any] | None:
    start, end = text.find("["), text.rfind("]")
    if start == -1 or end <= start:
        return None
    try:
        value = json.loads(text[start:end + 1])
    except json.JSONDecodeError:
        return None
    return value if isinstance(value, list) else None


def parse_rules(text: str, max_rules: int) -> tuple[tuple[str, ...], bool]:
    """(rules, unparseable). Accepts `{"rules": [...]}`, the paper's `{"experience_entry": [...]}`, or a
    bare list. Rules are stripped, de-duplicated, capped in number and length."""
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
        rule = " ".join(item.split())[:MAX_RULE_CHARS] if isinstance(item, str) else ""
        if rule and rule not in rules:
            rules.append(rule)
    return tuple(rules[:max_rules]), not rules


class Reflector:
    def __init__(self, benchmark: str, calls: ModelCalls, *, max_tokens: int = 512, max_rules: int = 3) -> None:
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
            max_rules=self.max_rules,
        )
        messages = [
            {"role": "system", "content": load_template(self.benchmark, "reflector").strip()},
            {"role": "user", "content": user},
        ]
        request = self.calls.request(
            "reflector", messages, call_key=call_key, max_tokens=self.max_tokens,
            json_schema=reflector_schema(self.max_rules),
        )
        result = await self.calls.ask(request)
        rules, unparseable = parse_rules(result.text, self.max_rules)
        record = self.calls.record
        record.reflections += 1
        record.reflection_tokens.append(result.prompt_tokens + result.completion_tokens)
        record.reflector_unparseable += int(unparseable)
        return Reflection(rules, unparseable, result)
