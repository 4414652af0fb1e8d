"""Judge: the logical-consistency validator of predict-act-verify.

It compares the planner's predicted state with the abstracted actual state and reports a mismatch
only for a direct factual contradiction (open vs closed, holding vs empty, in A vs on B); unrelated or
vaguer descriptions match by default. An answer that cannot be read as a verdict also counts as a
match (and is counted, `Verdict.unparseable`), so a weak judge model never invents learning signals.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from models.base import ChatResult
from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render

__all__ = ["JUDGE_SCHEMA", "Verdict", "parse_verdict", "Judge"]

JUDGE_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "verdict": {"type": "string", "enum": ["match", "mismatch"]},
        "reason": {"type": "string", "maxLength": 400},
    },
    "required": ["verdict", "reason"],
    "additionalProperties": False,
}

_MATCH_WORDS = {"match": True, "mismatch": False, "true": True, "false": False}


@dataclass(frozen=True, slots=True)
class Verdict:
    match: bool
    reason: str
    unparseable: bool = False
    result: ChatResult | None = field(default=None, compare=False, repr=False)

    @property
    def verdict(self) -> Literal["match", "mismatch"]:
        return "match" if self.match else "mismatch"


def parse_verdict(text: str) -> Verdict:
    """`{"verdict": "match"|"mismatch", "reason": ...}`; the paper's `{"match": bool}` is read too."""
    try:
        obj = extract_first_json_object(text)
    except PlanParseError:
        return Verdict(True, "unparseable judge output; defaulting to match", unparseable=True)
    value = obj.get("verdict", obj.get("match"))
    if isinstance(value, str):
        value = _MATCH_WORDS.get(value.strip().casefold())
    if not isinstance(value, bool):
        return Verdict(True, "judge output has no verdict; defaulting to match", unparseable=True)
    reason = obj.get("reason")
    return Verdict(value, reason.strip() if isinstance(reason, str) else "")


class Judge:
    def __init__(self, benchmark: str, calls: ModelCalls, *, max_tokens: int = 256) -> None:
        self.benchmark = benchmark
        self.calls = calls
        self.max_tokens = max_tokens

    async def judge(
        self, *, predicted: str, actual: str, call_key: str, feedback: str | None = None
    ) -> Verdict:
        """The paper's validator sees the prediction and the actual state only. `feedback` (an
        option, off by default) adds the env feedback and a rule that invalid feedback contradicts an
        assumed change."""
        section = f"\nEnvironment feedback for the action: {feedback.strip()}\n" if feedback is not None else ""
        user = render(
            load_template("common", "judge_user"),
            predicted=predicted.strip(), actual=actual.strip(), feedback_section=section,
        )
        system = load_template(self.benchmark, "judge").strip()
        if feedback is not None:
            rules_end = system.index("\n\nAnswer with")
            system = system[:rules_end] + "\n" + load_template("common", "judge_feedback_rule").rstrip() + system[rules_end:]
        messages = [
            {"role": "system", "content": system},
            {"role": "user", "content": user},
        ]
        request = self.calls.request(
            "judge", messages, call_key=call_key, max_tokens=self.max_tokens, json_schema=JUDGE_SCHEMA
        )
        result = await self.calls.ask(request, call_key=call_key)
        verdict = parse_verdict(result.text)
        record = self.calls.stats
        record.judge_calls += 1
        record.judge_mismatches += int(not verdict.match)
        record.judge_unparseable += int(verdict.unparseable)
        return Verdict(verdict.match, verdict.reason, verdict.unparseable, result)
