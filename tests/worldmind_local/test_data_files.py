"""The strict data-file readers every benchmark loader uses (issue 18, point 6)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from worldmind_local.data import data_file, finite_number, read_json_file
from worldmind_local.env import TaskDataError


def test_read_json_file_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    path.write_bytes(b'{\n"a": 1,\n"b": "\xff"\n}')
    with pytest.raises(TaskDataError, match="not UTF-8") as err:
        read_json_file(path)
    assert err.value.path == str(path) and err.value.field == "<line 3>"
    path.write_text('{\n"a": 1,\n"b": }')
    with pytest.raises(TaskDataError, match="column 6") as err:
        read_json_file(path)
    assert err.value.field == "<line 3>"
    path.write_text("[" * 100_000)
    with pytest.raises(TaskDataError, match="nested too deeply"):
        read_json_file(path)
    with pytest.raises(FileNotFoundError):
        read_json_file(tmp_path / "absent.json")


def test_numbers_decode_so_that_the_field_can_be_named(tmp_path: Path) -> None:
    path = tmp_path / "n.json"
    path.write_text('{"nan": NaN, "inf": 1e999, "big": ' + "9" * 5000 + ', "ok": 12}')
    data = read_json_file(path)
    assert math.isnan(data["nan"]) and data["inf"] == math.inf and data["big"] == math.inf and data["ok"] == 12


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 10**400, True, "1", None, [1]])
def test_finite_number_refuses(value: object) -> None:
    with pytest.raises(TaskDataError, match="expected a finite number") as err:
        finite_number("f.json", "tasks[2].x", value)
    assert err.value.field == "tasks[2].x" and len(str(err.value)) < 200


def test_finite_number_accepts() -> None:
    assert finite_number("f", "x", 3) == 3.0 and finite_number("f", "x", -1.5) == -1.5


def test_data_file_stays_inside_the_folder(tmp_path: Path) -> None:
    folder = tmp_path / "scenes"
    folder.mkdir()
    assert data_file(folder, "FloorPlan12", ".json", "b.json", "tasks[0].scene") == folder / "FloorPlan12.json"
    for name in ("../x", "/etc/passwd", "..", "", "a/b", "a\\b", ".x", 5, None):
        with pytest.raises(TaskDataError) as err:
            data_file(folder, name, ".json", "b.json", "tasks[0].scene")
        assert err.value.field == "tasks[0].scene"
    (folder / "Escape.json").symlink_to(tmp_path / "outside.json")
    with pytest.raises(TaskDataError, match="resolves outside"):
        data_file(folder, "Escape", ".json", "b.json", "tasks[0].scene")
