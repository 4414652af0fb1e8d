"""Loading EB-Navigation's subset files, and clear errors for malformed ones."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.data import SUBSETS, load_records, parse_object_id
from worldmind_local.env import TaskDataError


def test_all_five_subsets_load_in_order(eb_data_dir: Path) -> None:
    for subset in SUBSETS:
        tasks = ADAPTER.load_tasks(eb_data_dir, subset)
        raw = json.loads((eb_data_dir / "eb_navigation" / f"{subset}.json").read_text())["tasks"]
        assert len(tasks) == 60
        assert [t.index for t in tasks] == list(range(60))
        assert [t.instruction for t in tasks] == [r["instruction"] for r in raw]
        assert [t.payload["record"] for t in tasks] == raw  # the record is kept verbatim
        assert {t.task_type for t in tasks} == {"kitchen", "living_room", "bedroom"}
        assert len({t.id for t in tasks}) == 60


def test_parse_object_id() -> None:
    assert parse_object_id("Bread|+01.30|+00.98|-01.53") == ("Bread", 1.30, 0.98, -1.53)
    assert parse_object_id("GarbageCan|-07.10|00.00|+02.29") == ("GarbageCan", -7.10, 0.0, 2.29)
    assert parse_object_id("Bread") is None
    assert parse_object_id("Bread|x|y|z") is None


def _pack_with(tmp_path: Path, eb_data_dir: Path, edit) -> Path:  # type: ignore[no-untyped-def]
    nav = tmp_path / "eb_navigation"
    nav.mkdir()
    data = json.loads((eb_data_dir / "eb_navigation" / "base.json").read_text())
    edit(data)
    (nav / "base.json").write_text(json.dumps(data))
    return tmp_path


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["tasks"][3]["agentPose"].__setitem__("rotation", 45.0), "tasks[3].agentPose.rotation"),
        (lambda d: d["tasks"][5].pop("target_position"), "tasks[5].target_position"),
        (lambda d: d["tasks"][0]["target_position"].__setitem__("z", "far"), "tasks[0].target_position.z"),
        (lambda d: d["tasks"][7].__setitem__("targetObjectIds", "Bread"), "tasks[7].targetObjectIds"),
        (lambda d: d["tasks"][2].__setitem__("instruction", ""), "tasks[2].instruction"),
        (lambda d: d["tasks"][1]["agentPose"].__setitem__("horizon", 45), "tasks[1].agentPose.horizon"),
        (lambda d: d.pop("tasks"), "tasks"),
    ],
)
def test_malformed_file_names_file_and_field(tmp_path: Path, eb_data_dir: Path, edit, field: str) -> None:  # type: ignore[no-untyped-def]
    data_dir = _pack_with(tmp_path, eb_data_dir, edit)
    with pytest.raises(TaskDataError) as err:
        load_records(data_dir, "base")
    assert err.value.field == field
    assert "base.json" in str(err.value)


def test_invalid_json_is_a_task_data_error(tmp_path: Path) -> None:
    (tmp_path / "eb_navigation").mkdir()
    (tmp_path / "eb_navigation" / "base.json").write_text("{not json")
    with pytest.raises(TaskDataError, match="not valid JSON"):
        ADAPTER.load_tasks(tmp_path, "base")


def test_missing_subset_file_and_unknown_subset(tmp_path: Path, eb_data_dir: Path) -> None:
    shutil.copytree(eb_data_dir / "eb_navigation", tmp_path / "eb_navigation")
    (tmp_path / "eb_navigation" / "long_horizon.json").unlink()
    assert ADAPTER.has_data(tmp_path)
    with pytest.raises(FileNotFoundError, match="long_horizon.json"):
        ADAPTER.load_tasks(tmp_path, "long_horizon")
    with pytest.raises(ValueError, match="unknown EB-Navigation subset"):
        ADAPTER.load_tasks(tmp_path, "spatial")
    assert len(ADAPTER.load_tasks(tmp_path, "base")) == 60  # the other subsets still load


def test_has_data(tmp_path: Path, eb_data_dir: Path) -> None:
    assert ADAPTER.has_data(eb_data_dir)
    assert not ADAPTER.has_data(tmp_path)
