"""Hostile EB-Navigation data files (issue 18, point 6): one TaskDataError naming file, record and
field, and a record's `scene` can never make the loader open a file outside the data pack."""

from __future__ import annotations

import copy
import json
import pathlib
from pathlib import Path
from typing import Any

import pytest

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.data import load_records
from worldmind_local.env import TaskDataError

RECORD: dict[str, Any] = {
    "targetObjectType": "Bread",
    "targetObjectIds": "Bread|+01.30|+00.98|-01.53",
    "target_position": {"x": 1.3, "y": 0.98, "z": -1.53},
    "agentPose": {"position": {"x": -1.5, "y": 0.9, "z": -0.9}, "rotation": 90.0, "horizon": 0.0},
    "scene": "FloorPlan1",
    "instruction": "navigate to the bread",
    "object_to_hide": [],
}


def _write(data_dir: Path, records: list[Any], *, raw: str | None = None) -> Path:
    path = data_dir / "eb_navigation" / "base.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(raw if raw is not None else json.dumps({"tasks": records}, indent=1))
    return path


def _with(field: list[str], literal: str) -> str:
    rec = copy.deepcopy(RECORD)
    node = rec
    for key in field[:-1]:
        node = node[key]
    node[field[-1]] = "@V@"
    return json.dumps({"tasks": [RECORD, rec]}).replace('"@V@"', literal)


def test_a_clean_record_loads(tmp_path: Path) -> None:
    _write(tmp_path, [RECORD])
    assert load_records(tmp_path, "base")[0]["scene"] == "FloorPlan1"


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999", "9" * 400, "9" * 5000])
@pytest.mark.parametrize("field", [["target_position", "x"], ["agentPose", "position", "z"], ["agentPose", "rotation"]])
def test_non_finite_or_overflowing_positions_name_the_field(tmp_path: Path, literal: str, field: list[str]) -> None:
    path = _write(tmp_path, [], raw=_with(field, literal))
    with pytest.raises(TaskDataError) as err:
        load_records(tmp_path, "base")
    assert err.value.path == str(path.resolve()) and err.value.field == "tasks[1]." + ".".join(field)


@pytest.mark.parametrize("object_id", ["Bread|nan|0|0", "Bread|inf|0|0", "Bread|1e999|0|0"])
def test_object_ids_with_non_finite_coordinates_are_refused(tmp_path: Path, object_id: str) -> None:
    _write(tmp_path, [{**RECORD, "targetObjectIds": object_id}])
    with pytest.raises(TaskDataError) as err:
        load_records(tmp_path, "base")
    assert err.value.field == "tasks[0].targetObjectIds"


@pytest.mark.parametrize("scene", ["../../../etc/passwd", "/etc/passwd", "FloorPlan1/../../x", "..", ".hidden",
                                   "Floor Plan", "a\x00b", "x" * 300, 7])
def test_a_scene_that_is_not_a_plain_name_is_refused(tmp_path: Path, scene: Any) -> None:
    _write(tmp_path, [{**RECORD, "scene": scene}])
    with pytest.raises(TaskDataError) as err:
        load_records(tmp_path, "base")
    assert err.value.field == "tasks[0].scene"


def test_nothing_outside_the_data_folder_is_opened(tmp_path: Path, monkeypatch) -> None:
    """A scene file that is a symlink out of the pack is refused before anything is read."""
    data_dir, outside = tmp_path / "data", tmp_path / "outside.json"
    outside.write_text(json.dumps({"receptacles": {}}))
    scenes = data_dir / "eb_alfred" / "scenes"
    scenes.mkdir(parents=True)
    (scenes / "FloorPlan7.json").symlink_to(outside)
    _write(data_dir, [{**RECORD, "scene": "FloorPlan7"}])
    opened: list[Path] = []
    real = pathlib.Path.read_bytes

    def spy(self: Path) -> bytes:
        opened.append(self.resolve())
        return real(self)

    monkeypatch.setattr(pathlib.Path, "read_bytes", spy)
    with pytest.raises(TaskDataError, match="resolves outside") as err:
        ADAPTER.load_tasks(data_dir, "base")
    assert err.value.field == "tasks[0].scene"
    assert opened and all(p.is_relative_to(data_dir.resolve()) for p in opened)


def test_non_utf8_and_non_object_records(tmp_path: Path) -> None:
    path = _write(tmp_path, [RECORD])
    lines = path.read_bytes().split(b"\n")
    lines[2] += b"\x80"
    path.write_bytes(b"\n".join(lines))
    with pytest.raises(TaskDataError, match="not UTF-8") as err:
        load_records(tmp_path, "base")
    assert err.value.field == "<line 3>"
    _write(tmp_path, [RECORD, 5])
    with pytest.raises(TaskDataError) as err:
        load_records(tmp_path, "base")
    assert err.value.field == "tasks[1]"
    _write(tmp_path, [], raw="[" * 100_000)
    with pytest.raises(TaskDataError):
        load_records(tmp_path, "base")
