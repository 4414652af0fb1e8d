"""Hostile EB-Habitat data files (issue 18, point 6): one TaskDataError naming file, record and field."""

from __future__ import annotations

import json

import pytest

from benchmarks.eb_habitat.data import load_episodes
from worldmind_local.env import TaskDataError


def _file(episode: dict) -> dict:
    return {"subset": "base", "n_episodes": 1, "episodes": [episode]}


def test_non_utf8_names_the_file_and_line(write_subset, episode) -> None:
    data_dir = write_subset("base", json.dumps(_file(episode), indent=1))
    path = data_dir / "eb_habitat" / "base.json"
    lines = path.read_bytes().split(b"\n")
    lines[5] += b"\xc3\x28"
    path.write_bytes(b"\n".join(lines))
    with pytest.raises(TaskDataError, match="not UTF-8") as err:
        load_episodes(data_dir, "base")
    assert err.value.path == str(path) and err.value.field == "<line 6>"


@pytest.mark.parametrize("literal", ["9" * 5000, "NaN", "1e999", "true"])
def test_a_bad_index_names_the_record_and_field(write_subset, episode, literal: str) -> None:
    episode["index"] = "@I@"
    data_dir = write_subset("base", json.dumps(_file(episode)).replace('"@I@"', literal))
    with pytest.raises(TaskDataError) as err:
        load_episodes(data_dir, "base")
    assert err.value.field == "episodes[0].index" and err.value.path.endswith("base.json")


@pytest.mark.parametrize("content", ["[" * 100_000, '{"episodes": [' + "[" * 5000 + "]" * 5000 + "]}"])
def test_absurd_nesting_is_a_data_error(write_subset, content: str) -> None:
    with pytest.raises(TaskDataError) as err:
        load_episodes(write_subset("base", content), "base")
    assert err.value.path.endswith("base.json")


@pytest.mark.parametrize("record", [5, "episode", [1, 2], None])
def test_a_non_object_episode_names_its_position(write_subset, record) -> None:
    with pytest.raises(TaskDataError) as err:
        load_episodes(write_subset("base", {"episodes": [record]}), "base")
    assert err.value.field == "episodes[0]"
