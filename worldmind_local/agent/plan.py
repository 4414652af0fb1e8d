"""The planner's output: its JSON schema, tolerant parsing, the cascading skip, and id screening.

The planner answers `{"language_plan": str, "executable_plan": [{"action_id", "action_name",
"predicted_state"}]}`. `predicted_state` is the exact skip string when the target is not grounded
(the paper's Case B); once one action skips, every later action of the same plan is treated as
skipped too (the cascading-skip rule), so it is never verified.

What happens to an output that cannot be used follows EmbodiedBench's evaluators (EB @ b247936,
`planner/vlm_planner.py::json_to_action` and `planner/nav_planner.py::json_to_action`), per benchmark:

- EB-ALFRED / EB-Habitat (`POLICY_INVALID`): unparseable JSON counts as one invalid action
  (`planner_output_error` +1, invalid count +1) WITHOUT stepping the env and without adding anything
  to the planner's history; an empty plan ends the episode; an out-of-range action id truncates the
  plan there (an out-of-range FIRST id makes the whole output one invalid action, not a JSON error).
- EB-Navigation (`POLICY_RANDOM`): an unparseable output (a JSON error) or an empty plan executes one
  uniformly random action instead; an out-of-range id goes to the env unchanged, and EB's env answers
  it by issuing THOR's `Done` (EBNavEnv.py:253-256), as the twin does. Our randomness is seeded, so runs
  repeat exactly. Which policy a benchmark follows is its adapter's fact (`unusable_output`).

An action id that does not match the name written next to it is executed by id (EB reads only the id).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

from worldmind_local.agent.jsonparse import extract_json_object

__all__ = [
    "SKIP_STRING",
    "POLICY_INVALID",
    "POLICY_RANDOM",
    "PlanParseError",
    "PlannedAction",
    "Plan",
    "planner_schema",
    "extract_first_json_object",
    "parse_plan",
    "is_skip",
    "screen_ids",
]

SKIP_STRING = "Exploration phase: target not visible, prediction skipped."

UnusablePolicy = Literal["invalid", "random"]
POLICY_INVALID: UnusablePolicy = "invalid"
POLICY_RANDOM: UnusablePolicy = "random"

_SKIP_NORMAL = " ".join(SKIP_STRING.casefold().rstrip(".").split())


class PlanParseError(ValueError):
    """The planner output holds no usable plan object (EB's `output_json_error`)."""


@dataclass(frozen=True, slots=True)
class PlannedAction:
    action_id: int
    action_name: str          # as the planner wrote it (may disagree with the id)
    predicted_state: str | None
    skipped: bool


@dataclass(frozen=True, slots=True)
class Plan:
    language_plan: str
    actions: tuple[PlannedAction, ...]

    @property
    def empty(self) -> bool:
        return not self.actions


# Length bounds of the free-text fields. A constrained decoder then always closes the object within
# a known token budget: a weak model that repeats itself cannot run into max_tokens and turn a plan
# into malformed JSON (which EB counts as an invalid action).
MAX_LANGUAGE_PLAN_CHARS = 800
MAX_ACTION_NAME_CHARS = 80
MAX_PREDICTED_STATE_CHARS = 240


def planner_schema(n_actions: int, max_plan_actions: int) -> dict[str, Any]:
    """JSON schema for structured decoding. Ids are bounded by the episode's action space, so a
    backend that enforces the schema can never produce an out-of-range id; strings and the plan
    length are bounded so the answer always fits its token budget."""
    item = {
        "type": "object",
        "properties": {
            "action_id": {"type": "integer", "minimum": 0, "maximum": max(n_actions - 1, 0)},
            "action_name": {"type": "string", "maxLength": MAX_ACTION_NAME_CHARS},
            "predicted_state": {"type": "string", "maxLength": MAX_PREDICTED_STATE_CHARS},
        },
        "required": ["action_id", "action_name", "predicted_state"],
        "additionalProperties": False,
    }
    return {
        "type": "object",
        "properties": {
            "language_plan": {"type": "string", "maxLength": MAX_LANGUAGE_PLAN_CHARS},
            "executable_plan": {"type": "array", "items": item, "maxItems": max_plan_actions},
        },
        "required": ["language_plan", "executable_plan"],
        "additionalProperties": False,
    }


def extract_first_json_object(text: str) -> dict[str, Any]:
    """The first balanced JSON object in `text`, ignoring code fences and prose around it.

    Models often wrap JSON in ```json fences or add a sentence before it; we accept that (a tolerance
    EB's plain `json.loads` lacks, the same one the WorldMind authors added). Total, linear in the
    text and bounded (see `jsonparse`): any string gives a dict or PlanParseError, nothing else.
    """
    return extract_json_object(text)


def is_skip(predicted_state: str | None) -> bool:
    """The skip string, forgiving case, spacing, underscores for spaces (small models write
    "exploration_phase") and the final full stop; the words themselves must be exact."""
    if not predicted_state:
        return False
    text = predicted_state.casefold().replace("_", " ").strip().strip("\"'").rstrip(".")
    return " ".join(text.split()) == _SKIP_NORMAL


def _parse_item(i: int, item: Any) -> tuple[int, str, str | None]:
    if not isinstance(item, dict):
        raise PlanParseError(f"executable_plan[{i}] is not an object")
    action_id = item.get("action_id")
    if isinstance(action_id, bool) or not isinstance(action_id, int):
        raise PlanParseError(f"executable_plan[{i}].action_id is not an integer: {action_id!r}")
    name = item.get("action_name")
    pred = item.get("predicted_state")
    pred_text = pred.strip() if isinstance(pred, str) and pred.strip() else None
    return action_id, name if isinstance(name, str) else "", pred_text


def parse_plan(text: str) -> Plan:
    """Parse a planner output, applying the cascading skip. Raises PlanParseError when unusable."""
    obj = extract_first_json_object(text)
    if "executable_plan" not in obj:
        raise PlanParseError("missing key 'executable_plan'")
    raw_plan = obj["executable_plan"]
    if not isinstance(raw_plan, list):
        raise PlanParseError("'executable_plan' is not a list")
    language_plan = obj.get("language_plan")
    actions: list[PlannedAction] = []
    skipping = False
    for i, item in enumerate(raw_plan):
        action_id, name, pred = _parse_item(i, item)
        skipping = skipping or is_skip(pred)
        actions.append(PlannedAction(action_id, name, SKIP_STRING if skipping else pred, skipping))
    return Plan(language_plan if isinstance(language_plan, str) else "", tuple(actions))


def screen_ids(plan: Plan, n_actions: int, policy: UnusablePolicy) -> tuple[PlannedAction, ...]:
    """The actions to execute. Under the invalid policy the plan stops before the first out-of-range
    id (an empty result then means "one invalid action"); under the random policy every action is
    kept: an out-of-range id reaches the env as it is."""
    if policy == POLICY_RANDOM:
        return plan.actions
    for i, action in enumerate(plan.actions):
        if not 0 <= action.action_id < n_actions:
            return plan.actions[:i]
    return plan.actions
