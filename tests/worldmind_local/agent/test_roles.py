from __future__ import annotations

import json

import pytest

from worldmind_local.agent.distiller import annotate_trajectory, parse_workflow
from worldmind_local.agent.judge import parse_verdict
from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.agent.prompting import (
    PROMPT_BENCHMARKS,
    ROLE_TEMPLATES,
    TemplateError,
    format_experience,
    load_template,
    planner_messages,
    render,
)
from worldmind_local.agent.reflector import MAX_RULE_CHARS, parse_rules, reflector_schema
from worldmind_local.records import StepRecord


@pytest.mark.parametrize("text,match", [
    ('{"verdict": "match", "reason": "fine"}', True),
    ('{"verdict": "Mismatch", "reason": "open vs closed"}', False),
    ('{"match": false, "reason": "holding vs empty"}', False),
    ('{"match": "true", "reason": ""}', True),
])
def test_verdicts_are_read(text: str, match: bool) -> None:
    verdict = parse_verdict(text)
    assert (verdict.match, verdict.unparseable) == (match, False)
    assert verdict.verdict == ("match" if match else "mismatch")


@pytest.mark.parametrize("garbage", ["", "I think they match", '{"verdict": "maybe"}', '{"reason": "x"}', "{"])
def test_unreadable_verdict_defaults_to_match_and_says_so(garbage: str) -> None:
    verdict = parse_verdict(garbage)
    assert verdict.match and verdict.unparseable


def test_rules_from_object_paper_key_and_bare_list() -> None:
    assert parse_rules('{"rules": [" Open  the fridge first. ", "", "Open the fridge first."]}', 3) == (
        ("Open the fridge first.",), False)
    assert parse_rules('{"experience_entry": ["a", "b", "c", "d"]}', 2) == (("a", "b"), False)
    assert parse_rules('Rules: ["only one"]', 3) == (("only one",), False)
    assert parse_rules('{"rules": "single"}', 3) == (("single",), False)


def test_unusable_rules_are_flagged() -> None:
    assert parse_rules("no rules today", 3) == ((), True)
    assert parse_rules('{"rules": []}', 3) == ((), True)
    assert parse_rules('{"other": ["x"]}', 3) == ((), True)
    # a long reflection is kept whole (the paper's shape ends with the general "Therefore ..." part)
    long_text = ("My prediction that the apple would be in my hand failed because it was inside the closed "
                 "fridge. " * 8) + "Therefore open a closed container before picking up what is inside it."
    assert len(long_text) > 300
    assert parse_rules(json.dumps({"rules": [long_text]}), None) == ((long_text,), False)
    assert parse_rules(json.dumps({"rules": ["a", "b", "c", "d", "e"]}), None)[0] == ("a", "b", "c", "d", "e")
    assert reflector_schema(None)["properties"]["rules"].get("maxItems") is None
    assert reflector_schema(None)["properties"]["rules"]["items"]["maxLength"] == MAX_RULE_CHARS >= 1000


def test_workflow_parsing() -> None:
    assert parse_workflow('{"workflow": " Find,  pick,\\n place. "}') == "Find, pick, place."
    assert parse_workflow('{"success_experience": "Paper key."}') == "Paper key."
    assert parse_workflow('{"workflow": ""}') is None
    assert parse_workflow("just prose") is None


def _step(i: int, progress: float, env_step: bool = True) -> StepRecord:
    return StepRecord(step=i, plan_index=0, env_step=env_step, action_id=i, action_name=f"act {i}",
                      feedback="Last action executed successfully.", progress=progress)


def test_trajectory_marks_progress_increases_and_skips_non_env_steps() -> None:
    text = annotate_trajectory([_step(1, 0.0), _step(1, 0.0, env_step=False), _step(2, 0.5), _step(3, 0.5),
                                _step(4, 1.0)])
    lines = text.splitlines()
    assert len(lines) == 4
    assert "progress increased by 0.50" in lines[1] and "progress increased" not in lines[2]
    assert lines[3].endswith("progress increased by 0.50") and "task_progress: 1.00" in lines[3]


@pytest.mark.parametrize("benchmark", PROMPT_BENCHMARKS)
def test_every_benchmark_has_every_role_prompt(benchmark: str) -> None:
    for role in ROLE_TEMPLATES:
        assert len(load_template(benchmark, role)) > 200
    messages = planner_messages(benchmark, actions=["a0", "a1", "a2"], instruction="Do it.",
                                observation="You see a table.", history=[], max_plan_actions=7)
    system, user = messages[0]["content"], messages[1]["content"]
    assert "action id 0: a0\naction id 1: a1\naction id 2: a2" in system
    assert SKIP_STRING in system and "at most 7 actions" in system and "{{" not in system
    assert "Do it." in user and "You see a table." in user and "{{" not in user


def test_planner_user_message_holds_experience_history_and_image() -> None:
    class E:
        def __init__(self, text: str) -> None:
            self.text = text

    history = [_step(1, 0.0), _step(1, 0.0, env_step=False)]
    messages = planner_messages("eb_alfred", actions=["a0", "a1", "a2"], instruction="Do it.",
                                observation="obs", history=history, image="IMG",
                                experience=format_experience([E("Workflow G.")], [E("Rule P1."), E("Rule P2.")]))
    content = messages[1]["content"]
    assert content[0] == {"type": "image", "image": "IMG"}
    text = content[1]["text"]
    assert "1. Workflow G." in text and "1. Rule P1.\n2. Rule P2." in text
    assert "Step 0, action id 1, act 1, env feedback: Last action executed successfully." in text
    assert "Step 1" not in text


def test_experience_sections_are_left_out_when_empty() -> None:
    assert format_experience([], []) == ""


def test_render_refuses_missing_and_unused_values() -> None:
    assert render("a {{x}} b", x=1) == "a 1 b"
    with pytest.raises(TemplateError, match="missing"):
        render("a {{x}} {{y}}", x=1)
    with pytest.raises(TemplateError, match="unused"):
        render("a {{x}}", x=1, z=2)


def test_unknown_benchmark_prompts_are_a_clear_error() -> None:
    with pytest.raises(TemplateError, match="no prompts for benchmark 'eb_manipulation'"):
        load_template("eb_manipulation", "planner")
