"""EmbodiedBench's NL-Steps oracle plans on the twin: the mapping, the success rate and every failure.

The issue asks for >= 90% success. The twin reaches 71/100: every one of the 29 failures is listed in
nl_steps_failures.json with its reason and verdict (27 are plans that would fail in EmbodiedBench
too; 2 depend on AI2-THOR's metadata order). The twin is not bent to accept those plans.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.eb_alfred.data import load_pack
from benchmarks.eb_alfred.nl_steps import FAUCET_STEPS, NLStepError, map_nl_steps, map_step
from benchmarks.eb_alfred.twin import AlfredTwin
from worldmind_local.env import Task

FAILURES = json.loads((Path(__file__).parent / "nl_steps_failures.json").read_text())["failures"]


@pytest.mark.parametrize(
    ("step", "action"),
    [
        ("find a sinkbasin", "find a Sink"),
        ("find a bathtubbasin", "find a Bathtub"),
        ("find an apple", "find a Apple"),
        ("find a diningtable", "find a DiningTable"),
        ("pick up a ladle", "pick up the Ladle"),
        ("pick up the remotecontrol", "pick up the RemoteControl"),
        ("put down the ladle", "put down the object in hand"),
        ("turn on the floorlamp", "turn on the FloorLamp"),
        ("slice the apple", "slice the Apple"),
        ("find a cd", "find a CD"),
    ],
)
def test_step_mapping(step, action):
    assert map_step(step) == action


def test_unknown_steps_are_refused():
    with pytest.raises(NLStepError):
        map_step("find a unicorn")
    with pytest.raises(NLStepError):
        map_step("dance")


def test_faucet_inserted_after_the_put_into_the_sink_for_clean_tasks():
    steps = ["find a ladle", "pick up a ladle", "find a sinkbasin", "put down the ladle", "find a ladle"]
    clean = map_nl_steps(steps, "pick_clean_then_place_in_recep")
    assert clean[4:7] == list(FAUCET_STEPS) and clean[3] == "put down the object in hand"
    assert map_nl_steps(steps, "pick_and_place_simple") == [map_step(s) for s in steps]


def _replay(pack, subset, index, entry, env):
    key = f"{entry['full_scene_name']}#{entry['repeat_idx']}"
    record, facts = pack.tasks[key], pack.trials[entry["full_scene_name"]]
    task = Task(id=key, benchmark="eb_alfred", subset=subset, index=index, instruction=entry["task description"],
                task_type=record["task_type"], payload={"key": key, "record": record, "facts": facts})
    env.reset(task)
    result = None
    for action in map_nl_steps(entry["NL Steps"], record["task_type"]):
        result = env.step(env.action_id(action))
        if result.done:
            break
    return key, result


def test_nl_steps_replay_and_documented_failures(eb_data_dir):
    pack = load_pack(eb_data_dir)
    env = AlfredTwin()
    failed, total = {}, 0
    for subset in ("base", "common_sense"):
        entries = json.loads((pack.root / f"nl_steps_{subset}.json").read_text())
        for index, entry in enumerate(entries):
            key, result = _replay(pack, subset, index, entry, env)
            total += 1
            if not result.success:
                failed[(subset, index)] = (key, round(result.progress, 3))
    documented = {(f["subset"], f["index"]): (f["task"], f["progress"]) for f in FAILURES}
    assert failed == documented
    assert all(f["reason"] and f["verdict"] in ("plan", "twin", "undetermined") for f in FAILURES)
    assert not [f for f in FAILURES if f["verdict"] == "twin"]
    assert total == 100 and (total - len(failed)) / total >= 0.70
