"""Hostile EB-ALFRED data files (issue 18, point 6): one TaskDataError naming file, record and field."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.eb_alfred import ADAPTER
from worldmind_local.env import TaskDataError

TRIAL = "pick_and_place_simple-Apple-None-Fridge-0/trial_T0"
KEY = f"{TRIAL}#0"


@pytest.fixture
def pack(tmp_path: Path, make_task) -> Path:
    """A one-episode pack in EmbodiedBench's layout (as in test_data.py)."""
    task = make_task()
    apple, fridge = "Apple|+00.10|+01.00|+00.10", "Fridge|+03.00|+00.00|+00.00"
    task.payload["record"]["plan"]["high_pddl"] = [
        {"planner_action": {"action": "PickupObject", "objectId": apple}},
        {"planner_action": {"action": "PutObject", "objectId": apple, "receptacleObjectId": fridge}},
        {"planner_action": {"action": "NoOp"}},
    ]
    root = tmp_path / "eb_alfred"
    (root / "scenes").mkdir(parents=True)
    splits = {s: [{"task": TRIAL, "repeat_idx": 0, "instruction": "Put an apple in the fridge."}] for s in ADAPTER.subsets}
    (root / "splits.json").write_text(json.dumps(splits))
    (root / "tasks.json").write_text(json.dumps({KEY: task.payload["record"]}, indent=1))
    (root / "scenes" / "trial_initial_states.json").write_text(json.dumps({"trials": {TRIAL: task.payload["facts"]}}))
    return tmp_path


def _replace_x(pack: Path, literal: str) -> Path:
    path = pack / "eb_alfred" / "tasks.json"
    data = json.loads(path.read_text())
    data[KEY]["scene"]["init_action"]["x"] = "@X@"
    path.write_text(json.dumps(data).replace('"@X@"', literal))
    return path


def test_the_clean_pack_loads(pack: Path) -> None:
    assert len(ADAPTER.load_tasks(pack, "base")) == 1


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999", "9" * 400, "9" * 5000, "true", '"1"'])
def test_a_bad_position_names_the_record_and_field(pack: Path, literal: str) -> None:
    path = _replace_x(pack, literal)
    with pytest.raises(TaskDataError) as err:
        ADAPTER.load_tasks(pack, "base")
    assert err.value.path == str(path) and err.value.field == f"{KEY}.scene.init_action.x"
    assert "finite number" in str(err.value)


def test_non_utf8_names_the_file_and_line(pack: Path) -> None:
    path = pack / "eb_alfred" / "tasks.json"
    lines = path.read_bytes().split(b"\n")
    lines[3] += b" \xff\xfe"
    path.write_bytes(b"\n".join(lines))
    with pytest.raises(TaskDataError, match="not UTF-8") as err:
        ADAPTER.load_tasks(pack, "base")
    assert err.value.path.endswith("tasks.json") and err.value.field == "<line 4>"


def test_absurd_nesting_is_a_data_error(pack: Path) -> None:
    (pack / "eb_alfred" / "splits.json").write_text("[" * 100_000)
    with pytest.raises(TaskDataError) as err:
        ADAPTER.load_tasks(pack, "base")
    assert err.value.path.endswith("splits.json")


def test_a_non_object_split_entry_and_bad_object_ids(pack: Path) -> None:
    splits = pack / "eb_alfred" / "splits.json"
    splits.write_text(json.dumps({"base": [5]}))
    with pytest.raises(TaskDataError) as err:
        ADAPTER.load_tasks(pack, "base")
    assert err.value.field == "base[0]"


@pytest.mark.parametrize("coordinate", ["nan", "inf", "1e999", "x"])
def test_object_ids_with_non_finite_coordinates_are_refused(pack: Path, coordinate: str) -> None:
    path = pack / "eb_alfred" / "scenes" / "trial_initial_states.json"
    data = json.loads(path.read_text())
    objects = data["trials"][TRIAL]["objects"]
    oid = next(iter(objects))
    bad = f"Book|{coordinate}|+00.80|+03.10"
    objects[bad] = objects.pop(oid)
    path.write_text(json.dumps(data))
    with pytest.raises(TaskDataError) as err:
        ADAPTER.load_tasks(pack, "base")
    assert err.value.field == f"trials.{TRIAL}.objects.{bad}"
