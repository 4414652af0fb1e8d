from __future__ import annotations

import json

import pytest

from worldmind_local.agent.plan import (
    POLICY_INVALID,
    POLICY_RANDOM,
    SKIP_STRING,
    PlanParseError,
    extract_first_json_object,
    is_skip,
    parse_plan,
    planner_schema,
    screen_ids,
)


def _plan(*items: dict) -> str:
    return json.dumps({"language_plan": "think", "executable_plan": list(items)})


def _item(i: int, pred: str = "state", name: str = "a") -> dict:
    return {"action_id": i, "action_name": name, "predicted_state": pred}


def test_skip_string_is_exact() -> None:
    assert SKIP_STRING == "Exploration phase: target not visible, prediction skipped."


def test_extracts_first_object_from_fences_and_prose() -> None:
    text = 'Sure! Here is my plan:\n```json\n{"language_plan": "a {brace} in a string \\" quote", ' \
           '"executable_plan": []}\n```\nand {"another": 1}'
    obj = extract_first_json_object(text)
    assert obj == {"language_plan": 'a {brace} in a string " quote', "executable_plan": []}


def test_skips_a_broken_object_and_takes_the_next_complete_one() -> None:
    assert extract_first_json_object('{bad json} {"executable_plan": []}') == {"executable_plan": []}


@pytest.mark.parametrize("text", ["", "no json here", '{"language_plan": "cut off', "[1, 2, 3]"])
def test_unusable_text_raises(text: str) -> None:
    with pytest.raises(PlanParseError):
        extract_first_json_object(text)


def test_cascading_skip_marks_every_later_action() -> None:
    plan = parse_plan(_plan(_item(0, "I see the apple."), _item(1, SKIP_STRING), _item(2, "I hold the apple."),
                            _item(3, "")))
    assert [a.skipped for a in plan.actions] == [False, True, True, True]
    assert plan.actions[0].predicted_state == "I see the apple."
    assert all(a.predicted_state == SKIP_STRING for a in plan.actions[1:])


@pytest.mark.parametrize("variant", [SKIP_STRING, SKIP_STRING.upper(), SKIP_STRING.rstrip("."),
                                     "  exploration phase:  target not visible, prediction skipped .",
                                     "exploration_phase: target not visible, prediction skipped"])
def test_skip_detection_forgives_case_space_and_full_stop(variant: str) -> None:
    assert is_skip(variant)


@pytest.mark.parametrize("other", [None, "", "Exploration phase", "target not visible"])
def test_other_predictions_are_not_skips(other: str | None) -> None:
    assert not is_skip(other)


def test_missing_or_empty_prediction_is_none_not_skip() -> None:
    plan = parse_plan(json.dumps({"language_plan": "x", "executable_plan": [{"action_id": 1},
                                                                           _item(2, "   ")]}))
    assert [(a.predicted_state, a.skipped, a.action_name) for a in plan.actions] == [(None, False, ""),
                                                                                      (None, False, "a")]


def test_empty_plan_parses_as_empty() -> None:
    plan = parse_plan(_plan())
    assert plan.empty and plan.language_plan == "think"


@pytest.mark.parametrize("obj,message", [
    ({"language_plan": "x"}, "missing key 'executable_plan'"),
    ({"executable_plan": {"action_id": 1}}, "not a list"),
    ({"executable_plan": ["find a Apple"]}, "not an object"),
    ({"executable_plan": [{"action_id": "3"}]}, "not an integer"),
    ({"executable_plan": [{"action_id": True}]}, "not an integer"),
    ({"executable_plan": [{"action_id": 2.0}]}, "not an integer"),
])
def test_malformed_plans_raise_with_the_reason(obj: dict, message: str) -> None:
    with pytest.raises(PlanParseError, match=message):
        parse_plan(json.dumps(obj))


def test_invalid_policy_truncates_at_first_out_of_range_id() -> None:
    plan = parse_plan(_plan(_item(0), _item(1), _item(9), _item(2)))
    assert [a.action_id for a in screen_ids(plan, 5, POLICY_INVALID)] == [0, 1]
    first_bad = parse_plan(_plan(_item(-1), _item(1)))
    assert screen_ids(first_bad, 5, POLICY_INVALID) == ()


def test_random_policy_keeps_every_action() -> None:
    plan = parse_plan(_plan(_item(0), _item(9)))
    assert [a.action_id for a in screen_ids(plan, 5, POLICY_RANDOM)] == [0, 9]


def test_policy_per_benchmark_follows_embodiedbench() -> None:
    from worldmind_local.registry import BENCHMARKS

    assert BENCHMARKS.get("eb_navigation").unusable_output == POLICY_RANDOM
    assert BENCHMARKS.get("eb_alfred").unusable_output == POLICY_INVALID
    assert BENCHMARKS.get("eb_habitat").unusable_output == POLICY_INVALID


def test_schema_bounds_ids_and_plan_length() -> None:
    schema = planner_schema(162, 20)
    items = schema["properties"]["executable_plan"]
    assert items["maxItems"] == 20
    assert items["items"]["properties"]["action_id"] == {"type": "integer", "minimum": 0, "maximum": 161}
    assert schema["required"] == ["language_plan", "executable_plan"]
