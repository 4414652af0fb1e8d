"""Total, linear, bounded parsing of model output (issue 18, point 5): every role's parser maps any
string to a value or its declared parse error, whatever a looping or hostile model writes."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

from worldmind_local.agent import jsonparse
from worldmind_local.agent.abstractor import parse_summary
from worldmind_local.agent.distiller import parse_workflow
from worldmind_local.agent.jsonparse import extract_json_list, extract_json_object, parse_json
from worldmind_local.agent.judge import parse_verdict
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object, parse_plan
from worldmind_local.agent.reflector import parse_rules
from worldmind_local.replay import PlanError, _parse

ROOT = Path(__file__).resolve().parents[3]
PLAN = {"language_plan": "go", "executable_plan": [{"action_id": 1, "action_name": "a", "predicted_state": "s"}]}


@pytest.fixture(scope="module")
def fuzz():
    spec = importlib.util.spec_from_file_location("fuzz_outputs", ROOT / "scripts" / "fuzz_outputs.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["fuzz_outputs"] = module
    spec.loader.exec_module(module)
    return module


HOSTILE = {
    "deep_braces": "{" * 5000,
    "deep_brackets_in_object": '{"a": ' + "[" * 5000 + "]" * 5000 + "}",
    "deep_closed": '{"a":' * 5000 + "1" + "}" * 5000,
    "huge_int": '{"executable_plan": [], "n": ' + "9" * 4301 + "}",
    "nan": '{"executable_plan": [], "n": NaN}',
    "infinity": '{"executable_plan": [], "n": -Infinity}',
    "overflow_float": '{"executable_plan": [], "n": 1e999}',
    "run_8k": "{[" * 4000,
    "run_100k_open": "[" * 100_000,
    "run_100k_braces": "{" * 100_000,
    "pairs_100k": '{"a": ' + "{}" * 50_000,
    "junk_objects": "{x}" * 30_000,
    "unterminated_string": '{"a": "' + "\\\"" * 50_000,
    "surrogates": '{"executable_plan": [], "x": "\ud800\udfff"}\x00',
    "bytes": bytes(range(256)).decode("latin-1"),
    "empty": "",
}


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_extraction_never_raises_anything_but_plan_parse_error(name: str) -> None:
    try:
        value = extract_json_object(HOSTILE[name])
    except PlanParseError:
        return
    assert isinstance(value, dict)


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_every_role_parser_is_total(name: str) -> None:
    text = HOSTILE[name]
    try:
        parse_plan(text)
    except PlanParseError:
        pass
    assert isinstance(parse_verdict(text).match, bool)
    rules, unparseable = parse_rules(text, 3)
    assert isinstance(rules, tuple) and isinstance(unparseable, bool)
    assert parse_workflow(text) is None or isinstance(parse_workflow(text), str)
    before, after, _ = parse_summary(text, "b", "a")
    assert isinstance(before, str) and isinstance(after, str)
    with pytest.raises(PlanError):
        _parse(text, 7)


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999", "9" * 101, "9" * 4301])
def test_non_finite_and_huge_numbers_are_refused(literal: str) -> None:
    with pytest.raises(PlanParseError):
        extract_json_object('{"a": ' + literal + "}")
    with pytest.raises(PlanParseError):
        parse_json("[" + literal + "]")


def test_numbers_within_bounds_parse() -> None:
    assert extract_json_object('{"a": ' + "9" * 100 + ', "b": -1.5e10}') == {"a": int("9" * 100), "b": -1.5e10}


def test_a_bad_number_skips_to_the_next_object() -> None:
    assert extract_json_object('{"a": NaN} then {"executable_plan": []}') == {"executable_plan": []}


def test_depth_limit_is_an_error_not_a_recursion_error() -> None:
    ok = '{"a": ' + "[" * 10 + "]" * 10 + "}"
    assert extract_json_object(ok, max_depth=11)["a"]
    with pytest.raises(PlanParseError, match="deeper than 10"):
        extract_json_object(ok, max_depth=10)
    with pytest.raises(PlanParseError, match="deeper than 64"):
        extract_json_object('{"a": ' + "[" * 65 + "]" * 65 + "}")
    with pytest.raises(PlanParseError):
        parse_json("[" * 65 + "]" * 65)


def test_text_past_max_chars_is_cut() -> None:
    text = json.dumps(PLAN) + " " * 10
    assert extract_json_object(text, max_chars=len(json.dumps(PLAN))) == PLAN
    with pytest.raises(PlanParseError, match="cut off"):
        extract_json_object(text, max_chars=20)


def test_fences_prose_and_braces_inside_strings() -> None:
    text = 'Here: "a quote\n```json\n' + json.dumps({**PLAN, "language_plan": "a {b} \" c"}) + "\n```\n{x}"
    assert extract_json_object(text)["language_plan"] == 'a {b} " c'


def test_nested_candidate_after_a_broken_outer_object() -> None:
    assert extract_json_object('{"broken": x, "inner": {"executable_plan": []}}') == {"executable_plan": []}
    with pytest.raises(PlanParseError):
        extract_json_object("{[}")


def test_plan_module_delegates_here() -> None:
    assert extract_first_json_object("```json\n" + json.dumps(PLAN) + "\n```") == PLAN


def test_non_text_is_a_parse_error() -> None:
    for value in (None, 3, b"{}"):
        with pytest.raises(PlanParseError):
            extract_json_object(value)  # type: ignore[arg-type]


def test_bare_list_and_whole_value() -> None:
    assert extract_json_list('rules:\n```json\n["a", "b"]\n```') == ["a", "b"]
    assert parse_rules('["open it first", "open it first"]', 3) == (("open it first",), False)
    assert parse_json(' {"a": [1, 2]}\r\n') == {"a": [1, 2]}
    with pytest.raises(PlanParseError, match="not valid JSON"):
        parse_json("{not json")


def test_candidate_and_scan_budgets_bound_the_work(monkeypatch) -> None:
    """Linear and bounded without timing anything: count the decoder calls and the scanned tokens."""
    calls = {"decode": 0}
    real = jsonparse._DECODER.raw_decode

    class Counting:
        def decode(self, s):
            calls["decode"] += 1
            return jsonparse.json.JSONDecoder.decode(real.__self__, s)

        def raw_decode(self, s, i=0):
            calls["decode"] += 1
            return real(s, i)

    monkeypatch.setattr(jsonparse, "_DECODER", Counting())
    with pytest.raises(PlanParseError):
        extract_json_object("{x}" * 60_000)
    assert calls["decode"] <= jsonparse.MAX_CANDIDATES + 1
    calls["decode"] = 0
    with pytest.raises(PlanParseError, match="brackets and strings"):
        extract_json_object('{"a": ' + "[1]" * 60_000)
    assert calls["decode"] == 1


def test_summary_fields_of_the_wrong_type_fall_back_to_the_env_text() -> None:
    assert parse_summary('{"state_before": 5, "state_after": "  "}', "b", "a") == ("b", "a", True)
    assert parse_summary("the apple is held", "b", "a") == ("b", "the apple is held", False)


def test_replay_plan_lines_are_total() -> None:
    with pytest.raises(PlanError, match="line 3: not UTF-8"):
        _parse(b'{"subset": "\xff"}'.decode("utf-8", "surrogateescape"), 3)
    with pytest.raises(PlanError, match="line 4: not valid JSON"):
        _parse('{"subset": "base", "index": ' + "9" * 5000 + ', "actions": []}', 4)
    assert _parse('{"subset": "base", "index": 2, "actions": ["x"]}', 1) == ("base", 2, ["x"])


@pytest.mark.parametrize("role", ["planner", "judge", "reflector", "distiller", "summarizer", "replay"])
def test_every_fuzz_class_is_handled(fuzz, role: str) -> None:
    """Each generated class, for each role: no exception escapes the parser."""
    import random

    gen = fuzz.Generator(role, random.Random(f"test:{role}"), fuzz._bracket_pool(random.Random(1)))
    classify = fuzz.CLASSIFIERS[role]
    for _name, make in gen.classes():
        for _ in range(15):
            classify(make())  # raises on a bug
    report = fuzz.fuzz_role(role, 200, seed=3)
    assert report.count == 200 and report.exceptions == []
