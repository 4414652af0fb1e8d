"""EmbodiedBench's NL-Steps oracle plans on the twin, in both translation modes, with every failure.

The issue asks for >= 90% success. The plain mapping reaches 71/100, the intent-preserving translation
(next instance for a pick_two's second object, open before a put into a closed openable receptacle)
88/100. Every failure of each mode is listed in nl_steps_failures.json with its cause and verdict (no
'twin' verdicts), and NL_STEPS_REPORT.md explains why the 90% bar is not reached without guessing. The
twin is not bent to accept those plans.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.eb_alfred.data import load_pack
from benchmarks.eb_alfred.nl_steps import (
    FAUCET_STEPS,
    NLStepError,
    map_nl_steps,
    map_step,
    trace_nl_steps,
    translate_nl_steps,
)
from benchmarks.eb_alfred.twin import AlfredTwin
from worldmind_local.env import Task

DOC = json.loads((Path(__file__).parent / "nl_steps_failures.json").read_text())
MODES = ("plain", "intent_preserving")
PUT = "put down the object in hand"
TWO_BOOKS = ["find a book", "pick up a book", "find a desk", "put down the book"] * 2


@pytest.mark.parametrize(
    ("step", "action"),
    [
        ("find a sinkbasin", "find a Sink"),
        ("find a bathtubbasin", "find a Bathtub"),
        ("find an apple", "find a Apple"),
        ("find a diningtable", "find a DiningTable"),
        ("pick up a ladle", "pick up the Ladle"),
        ("pick up the remotecontrol", "pick up the RemoteControl"),
        ("put down the ladle", PUT),
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
    assert clean[4:7] == list(FAUCET_STEPS) and clean[3] == PUT
    assert map_nl_steps(steps, "pick_and_place_simple") == [map_step(s) for s in steps]


def test_pick_two_second_visit_goes_to_the_next_instance_when_the_name_exists():
    names = ["find a Book", "find a Book_2", "find a Desk"]
    plan = translate_nl_steps(TWO_BOOKS, "pick_two_obj_and_place", names)
    assert plan[4] == "find a Book_2" and plan[:4] == map_nl_steps(TWO_BOOKS, "pick_two_obj_and_place")[:4]
    assert [s.rule for s in trace_nl_steps(TWO_BOOKS, "pick_two_obj_and_place", names)][4] == "next_instance"
    # one Book in the scene (no Book_2 action), another task type, or the plain mode: left as written
    assert translate_nl_steps(TWO_BOOKS, "pick_two_obj_and_place", ["find a Book"])[4] == "find a Book"
    assert translate_nl_steps(TWO_BOOKS, "pick_and_place_simple", names)[4] == "find a Book"
    assert map_nl_steps(TWO_BOOKS, "pick_two_obj_and_place")[4] == "find a Book"


def test_a_find_before_any_pick_of_that_type_keeps_the_bare_name():
    steps = ["find a book", "find a book", "pick up a book"]
    assert translate_nl_steps(steps, "pick_two_obj_and_place", ["find a Book_2"])[:2] == ["find a Book"] * 2


def test_open_inserted_before_a_put_into_an_unopened_openable_receptacle():
    steps = ["find a spatula", "pick up a spatula", "find a drawer", "put down the spatula"] * 2
    names = ["open the Drawer", "find a Spatula_2"]
    plan = translate_nl_steps(steps, "pick_two_obj_and_place", names)
    assert plan == ["find a Spatula", "pick up the Spatula", "find a Drawer", "open the Drawer", PUT,
                    "find a Spatula_2", "pick up the Spatula", "find a Drawer", PUT]  # still open: no second open


def test_open_uses_the_instance_name_of_the_find_and_respects_the_plans_own_open_and_close():
    names = ["open the Fridge", "open the Cabinet_3"]
    assert translate_nl_steps(["find a cabinet", "put down the cup"], "x", ["open the Cabinet"]) == [
        "find a Cabinet", "open the Cabinet", PUT]
    opened = ["find a fridge", "open the fridge", "put down the apple", "close the fridge"]
    assert translate_nl_steps(opened, "pick_cool_then_place_in_recep", names) == map_nl_steps(opened, "x")
    reput = [*opened, "find a fridge", "put down the apple"]
    assert translate_nl_steps(reput, "x", names)[-2:] == ["open the Fridge", PUT]
    # not openable, or no current receptacle (the put right after a pick is a drop): nothing inserted
    assert translate_nl_steps(["find a desk", "put down the book"], "x", names) == ["find a Desk", PUT]
    assert translate_nl_steps(["find a fridge", "pick up a apple", "put down the apple"], "x", names)[1:] == [
        "pick up the Apple", PUT]


def _task(pack, subset: str, index: int, entry: dict) -> Task:
    key = f"{entry['full_scene_name']}#{entry['repeat_idx']}"
    record, facts = pack.tasks[key], pack.trials[entry["full_scene_name"]]
    return Task(id=key, benchmark="eb_alfred", subset=subset, index=index, instruction=entry["task description"],
                task_type=record["task_type"], payload={"key": key, "record": record, "facts": facts})


def _replay_all(eb_data_dir):
    """Per mode: {(subset, index): (task key, progress)} of the failures, the success count, and the
    added or renamed actions the twin answered as invalid."""
    pack, env = load_pack(eb_data_dir), AlfredTwin()
    failed = {m: {} for m in MODES}
    wins = dict.fromkeys(MODES, 0)
    bad_inserts = set()
    for subset in ("base", "common_sense"):
        for index, entry in enumerate(json.loads((pack.root / f"nl_steps_{subset}.json").read_text())):
            task = _task(pack, subset, index, entry)
            for mode in MODES:
                env.reset(task)
                space = env.actions if mode == "intent_preserving" else None
                result = None
                for step in trace_nl_steps(entry["NL Steps"], task.task_type, space):
                    result = env.step(env.action_id(step.action))
                    if result.invalid and step.rule in ("open", "next_instance"):
                        bad_inserts.add((subset, index, step.action, result.feedback))
                    if result.done:
                        break
                if result.success:
                    wins[mode] += 1
                else:
                    failed[mode][(subset, index)] = (task.id, round(result.progress, 3))
    return failed, wins, bad_inserts


def test_nl_steps_replay_in_both_modes_and_documented_failures(eb_data_dir, record_property):
    failed, wins, bad_inserts = _replay_all(eb_data_dir)
    total = 100
    for mode in MODES:
        print(f"NL-Steps {mode}: {wins[mode]}/{total} succeed")
        record_property(f"nl_steps_{mode}_success", wins[mode])
        documented = {(f["subset"], f["index"]): (f["task"], f["progress"]) for f in DOC["failures"][mode]}
        assert failed[mode] == documented, mode
        assert DOC["summary"][mode] == {"episodes": total, "success": wins[mode]}
        assert wins[mode] + len(failed[mode]) == total
    entries = DOC["failures"]["plain"] + DOC["failures"]["intent_preserving"]
    assert all(f["reason"] and f["cause"] and f["verdict"] in ("plan", "undetermined") for f in entries)
    # the translation only ever helps: every plain success still succeeds
    assert set(failed["intent_preserving"]) <= set(failed["plain"])
    assert wins["plain"] >= 0.70 * total and wins["intent_preserving"] >= 0.88 * total
    documented_bad = {(b["subset"], b["index"], b["action"], b["feedback"]) for b in DOC["inserted_invalid"]}
    assert bad_inserts == documented_bad and all(b["why"] for b in DOC["inserted_invalid"])
