"""The generic replay: plan lines in, result lines out, bad lines reported and skipped over."""

from __future__ import annotations

import io
import json

from worldmind_local.data import load_suite
from worldmind_local.replay import Replayer, expert_lines, replay_episode, replay_lines


def suite():
    return load_suite("eb_alfred", suite="generated", seed=5, n_per_subset=3)


def test_expert_lines_replay_to_success():
    replayer = Replayer(suite())
    out = io.StringIO()
    n = replay_lines(replayer, expert_lines(replayer, ["base", "spatial"]), out)
    lines = [json.loads(x) for x in out.getvalue().splitlines()]
    assert n == 6 and all(r["success"] and r["progress"] == 1.0 for r in lines)
    assert set(lines[0]) >= {"subset", "index", "success", "progress", "steps", "invalid", "feedback"}
    assert len(lines[0]["feedback"]) == lines[0]["steps"] and lines[0]["end_reason"] == "success"
    assert replayer.scores["base"].sr == 1.0 and replayer.scores["spatial"].gc == 1.0


def test_bad_lines_become_error_lines_and_the_run_goes_on():
    replayer = Replayer(suite())
    task = replayer.tasks("base")[0]
    good = json.dumps({"subset": "base", "index": 0, "actions": list(task.expert_plan)})
    lines = [
        "{not json",
        json.dumps({"subset": "base", "index": 0, "actions": ["find a Unicorn"]}),
        json.dumps({"subset": "base", "index": 99, "actions": []}),
        json.dumps({"subset": "nope", "index": 0, "actions": []}),
        json.dumps({"subset": "base", "index": "0", "actions": []}),
        "",
        good,
    ]
    out = io.StringIO()
    assert replay_lines(replayer, lines, out) == 6
    results = [json.loads(x) for x in out.getvalue().splitlines()]
    assert "not valid JSON" in results[0]["error"] and results[0]["line"] == 1
    assert "find a Unicorn" in results[1]["error"] and results[1]["steps"] == 0
    assert "out of range" in results[2]["error"]
    assert "unknown subset" in results[3]["error"]
    assert "index" in results[4]["error"]
    assert results[5]["success"] and "error" not in results[5]
    assert replayer.skipped == 4 and replayer.scores["base"].episodes == 2


def test_actions_after_the_end_are_not_run():
    s = suite()
    task = s.tasks("base")[1]
    env = Replayer(s).env()
    result = replay_episode(env, task, list(task.expert_plan) + ["find a Fridge"] * 3)
    assert result["success"] and result["steps"] == len(task.expert_plan)


def test_invalid_actions_are_counted():
    s = suite()
    env = Replayer(s).env()
    result = replay_episode(env, s.tasks("base")[0], ["drop the object in hand"] * 4)
    assert result["invalid"] == 4 and result["steps"] == 4 and not result["success"]
    assert result["feedback"][0] == "Last action is invalid. Robot is not holding any object"


def test_env_refusing_a_task_is_an_error_line():
    replayer = Replayer(suite(), env_kind="embodiedbench")
    result = replayer.run_line(json.dumps({"subset": "base", "index": 0, "actions": ["find a Fridge"]}), 1)
    assert "twin only" in result["error"] and not result["success"]
    assert replayer.scores["base"].errors == 1 and replayer.skipped == 0
