"""Loading the data pack, and clear errors (file + field) for malformed files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks.eb_alfred import ADAPTER
from worldmind_local.env import BenchmarkAdapter, Env, TaskDataError

TRIAL = "pick_and_place_simple-Apple-None-Fridge-0/trial_T0"


def write_pack(root: Path, make_task) -> Path:
    """A one-episode pack in EmbodiedBench's layout, built from the test kitchen."""
    task = make_task()
    apple, fridge = "Apple|+00.10|+01.00|+00.10", "Fridge|+03.00|+00.00|+00.00"
    task.payload["record"]["plan"]["high_pddl"] = [
        {"planner_action": {"action": "PickupObject", "objectId": apple}},
        {"planner_action": {"action": "PutObject", "objectId": apple, "receptacleObjectId": fridge}},
        {"planner_action": {"action": "NoOp"}},
    ]
    pack = root / "eb_alfred"
    (pack / "scenes").mkdir(parents=True)
    splits = {s: [{"task": TRIAL, "repeat_idx": 0, "instruction": "Put an apple in the fridge."}] for s in ADAPTER.subsets}
    (pack / "splits.json").write_text(json.dumps(splits))
    (pack / "tasks.json").write_text(json.dumps({f"{TRIAL}#0": task.payload["record"]}))
    (pack / "scenes" / "trial_initial_states.json").write_text(json.dumps({"trials": {TRIAL: task.payload["facts"]}}))
    return root


def test_loads_all_subsets_in_order(eb_data_dir):
    for subset in ADAPTER.subsets:
        tasks = ADAPTER.load_tasks(eb_data_dir, subset)
        assert [t.index for t in tasks] == list(range(50))
        assert all(t.benchmark == "eb_alfred" and t.subset == subset and t.instruction for t in tasks)
    base = ADAPTER.load_tasks(eb_data_dir, "base")
    assert base[0].instruction == "Rinse off a ladle and move it to the table."
    assert base[0].task_type == "pick_clean_then_place_in_recep"
    assert ADAPTER.has_data(eb_data_dir) and not ADAPTER.has_data(eb_data_dir / "nowhere")


def test_tiny_pack_loads_and_plays(tmp_path, make_task):
    root = write_pack(tmp_path, make_task)
    tasks = ADAPTER.load_tasks(root, "spatial")
    assert len(tasks) == 1 and tasks[0].payload["split"]["task"] == TRIAL
    assert tasks[0].expert_plan == ("find a Apple", "pick up the Apple", "find a Fridge", "open the Fridge",
                                    "put down the object in hand")


@pytest.mark.parametrize(
    ("file", "mutate", "field"),
    [
        ("splits.json", lambda d: d["base"][0].pop("repeat_idx"), "base[0].repeat_idx"),
        ("splits.json", lambda d: d["base"][0].update(task="no-slash"), "base[0].task"),
        ("tasks.json", lambda d: d[f"{TRIAL}#0"].update(task_type="juggle"), f"{TRIAL}#0.task_type"),
        ("tasks.json", lambda d: d[f"{TRIAL}#0"]["pddl_params"].pop("parent_target"), f"{TRIAL}#0.pddl_params.parent_target"),
        ("tasks.json", lambda d: d[f"{TRIAL}#0"]["scene"]["init_action"].pop("x"), f"{TRIAL}#0.scene.init_action.x"),
        ("tasks.json", lambda d: d.pop(f"{TRIAL}#0"), f"{TRIAL}#0"),
        ("scenes/trial_initial_states.json", lambda d: d["trials"][TRIAL].pop("objects"), f"trials.{TRIAL}.objects"),
        ("scenes/trial_initial_states.json", lambda d: d["trials"][TRIAL].update(in_receptacle=[["a"]]), f"trials.{TRIAL}.in_receptacle"),
    ],
)
def test_malformed_file_names_file_and_field(tmp_path, make_task, file, mutate, field):
    root = write_pack(tmp_path, make_task)
    path = root / "eb_alfred" / file
    data = json.loads(path.read_text())
    mutate(data)
    path.write_text(json.dumps(data))
    with pytest.raises(TaskDataError) as err:
        ADAPTER.load_tasks(root, "base")
    assert err.value.field == field and err.value.path.endswith(file)
    assert file.split("/")[-1] in str(err.value) and field in str(err.value)


def test_broken_json_and_missing_files(tmp_path, make_task):
    root = write_pack(tmp_path, make_task)
    (root / "eb_alfred" / "tasks.json").write_text("{not json")
    with pytest.raises(TaskDataError, match="tasks.json"):
        ADAPTER.load_tasks(root, "base")
    (root / "eb_alfred" / "tasks.json").unlink()
    with pytest.raises(FileNotFoundError, match="tasks.json"):
        ADAPTER.load_tasks(root, "base")


def test_make_env_kinds():
    twin = ADAPTER.make_env("twin")
    assert isinstance(twin, Env) and isinstance(ADAPTER, BenchmarkAdapter)
    assert twin.max_steps == 30 and twin.max_invalid == 10 and ADAPTER.default_top_k == 2
    with pytest.raises(ValueError, match="twin"):
        ADAPTER.make_env("unity")
