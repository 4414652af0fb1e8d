"""The embedded action list is EmbodiedBench's: checked against the data pack's action_space.json."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.eb_navigation.actions import ACTION_TEXTS, ACTIONS, check_action_space_file
from worldmind_local.env import TaskDataError


def test_embedded_actions_equal_the_data_file(eb_data_dir: Path) -> None:
    data = json.loads((eb_data_dir / "eb_navigation" / "action_space.json").read_text())
    assert [a["text"] for a in data["actions"]] == list(ACTION_TEXTS)
    assert [a["thor_action"] for a in data["actions"]] == [a.thor_action for a in ACTIONS]
    assert [a["params"] for a in data["actions"]] == [a.params_dict() for a in ACTIONS]
    assert [a["id"] for a in data["actions"]] == list(range(8))
    check_action_space_file(eb_data_dir / "eb_navigation" / "action_space.json")  # does not raise


def test_action_texts_are_verbatim() -> None:
    assert ACTION_TEXTS[0] == "Move forward by 0.25"
    assert ACTION_TEXTS[4] == "Rotate to the right by 90 degrees."
    assert ACTION_TEXTS[7] == "Tilt the camera downward by 30 degrees."


def test_a_differing_action_file_is_refused_naming_the_field(tmp_path: Path, eb_data_dir: Path) -> None:
    data = json.loads((eb_data_dir / "eb_navigation" / "action_space.json").read_text())
    data["actions"][2]["text"] = "Move right by 0.25"
    path = tmp_path / "action_space.json"
    path.write_text(json.dumps(data))
    with pytest.raises(TaskDataError, match=r"actions\[2\]\.text") as err:
        check_action_space_file(path)
    assert str(path) in str(err.value)
