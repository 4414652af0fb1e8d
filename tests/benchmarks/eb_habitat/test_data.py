"""Episode loading and validation, and the embedded facts checked against the data pack."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

import benchmarks.eb_habitat as package
from benchmarks.eb_habitat import scene
from benchmarks.eb_habitat.actions import embedded_skills, load_skills, skills_for
from benchmarks.eb_habitat.data import SUBSETS, load_episodes
from worldmind_local.env import TaskDataError


@pytest.mark.embodiedbench_data
@pytest.mark.parametrize("subset", SUBSETS)
def test_all_six_subsets_load(eb_data_dir, subset):
    episodes = load_episodes(eb_data_dir, subset)
    assert len(episodes) == 50
    assert [e["index"] for e in episodes] == list(range(50))


@pytest.mark.embodiedbench_data
def test_embedded_skills_equal_the_data_file(eb_data_dir):
    from_file = load_skills(eb_data_dir / "eb_habitat" / "action_space.json")
    assert from_file == embedded_skills()
    assert skills_for(eb_data_dir) == skills_for(None)
    assert [s.text for s in from_file[16:19]] == [
        "pick up the ball",
        "pick up the clamp",
        "pick up the hammer",
    ]


@pytest.mark.embodiedbench_data
def test_categories_and_assets_equal_dataset_yaml(eb_data_dir):
    spec = yaml.safe_load((eb_data_dir / "eb_habitat" / "dataset.yaml").read_text())
    assert tuple(spec["category_groups"]["all_cats"]["included"]) == scene.CATEGORIES
    sets = {
        s["name"]: tuple(s["included_substrings"])
        for s in spec["object_sets"]
        if s["name"] != "CLUTTER_OBJECTS"
    }
    assert sets == scene.CATEGORY_ASSETS
    receps = {r["name"]: tuple(r["included_receptacle_substrings"]) for r in spec["receptacle_sets"]}
    assert (
        receps["all_receps"] == scene.RECEPTACLES and receps["open_air_receps"] == scene.OPEN_AIR_RECEPTACLES
    )


@pytest.mark.embodiedbench_data
def test_reach_table_is_the_majority_of_recorded_states(eb_data_dir):
    episodes = [e for s in SUBSETS for e in load_episodes(eb_data_dir, s)]
    derived = scene.derive_reach_table(episodes)
    assert len(derived) >= 9  # every place an expert stands at
    for place, near in derived.items():
        assert near == scene.REACH[place], place


@pytest.mark.embodiedbench_data
def test_markers_are_the_recorded_ones(eb_data_dir):
    episode = load_episodes(eb_data_dir, "base")[0]
    assert episode["markers"] == list(scene.MARKER_RECORDS)


def test_no_pickle_anywhere_in_the_package():
    for source in Path(package.__file__).parent.glob("*.py"):
        text = source.read_text()
        assert "import pickle" not in text and "pickle.load" not in text, source


def _episode_file(episode: dict) -> dict:
    return {"subset": "base", "n_episodes": 1, "episodes": [episode]}


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda e: e.update(index=3), "episodes[0].index"),
        (lambda e: e.update(instruction=""), "episodes[0].instruction"),
        (lambda e: e["rigid_objs"][2].update(category="spaceship"), "episodes[0].rigid_objs[2].category"),
        (
            lambda e: e["rigid_objs"][1].update(start_receptacle="moon"),
            "episodes[0].rigid_objs[1].start_receptacle",
        ),
        (lambda e: e.update(start_preds=["holding(013_apple_:0000)"]), "episodes[0].start_preds[0]"),
        (lambda e: e["goal_preds"]["sub_exprs"].append("fly(X)"), "episodes[0].goal_preds"),
        (lambda e: e["subgoals"][1].append("robot_at(nowhere)"), "episodes[0].subgoals[1]"),
        (
            lambda e: e["name_to_receptacle"].update(
                {"013_apple_:0000": "receptacle_aabb_Sofa_frl_apartment_sofa"}
            ),
            "episodes[0].name_to_receptacle",
        ),
    ],
)
def test_bad_records_name_the_file_and_field(episode, write_subset, change, field):
    change(episode)
    data_dir = write_subset("base", _episode_file(episode))
    with pytest.raises(TaskDataError) as info:
        load_episodes(data_dir, "base")
    assert info.value.field == field and info.value.path.endswith("base.json")


def test_unreadable_and_missing_files(write_subset, tmp_path):
    with pytest.raises(TaskDataError, match="not valid JSON"):
        load_episodes(write_subset("base", "{not json"), "base")
    with pytest.raises(TaskDataError, match="'episodes'"):
        load_episodes(write_subset("base", {"episodes": 5}), "base")
    with pytest.raises(TaskDataError, match="missing"):
        load_episodes(tmp_path, "long_horizon")
    with pytest.raises(ValueError, match="unknown EB-Habitat subset"):
        load_episodes(tmp_path, "spatial")


def test_bad_action_space_file(tmp_path):
    path = tmp_path / "action_space.json"
    skills = [
        {"id": s.id, "pddl_action": s.pddl_action, "args": list(s.args), "text": s.text}
        for s in embedded_skills()
    ]
    skills[5]["pddl_action"] = "teleport"
    path.write_text(json.dumps({"actions": skills}))
    with pytest.raises(TaskDataError) as info:
        load_skills(path)
    assert info.value.field == "actions[5].pddl_action"
