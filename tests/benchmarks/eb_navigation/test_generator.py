"""Generated EB-Navigation suites: EmbodiedBench's record format, deterministic, expert plans succeed."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmarks.eb_navigation import ADAPTER, generator
from benchmarks.eb_navigation.data import validate_record
from benchmarks.eb_navigation.observe import Pose, visible_objects

N = 100
REPO = Path(__file__).resolve().parents[3]


def _dump(tasks) -> str:  # type: ignore[no-untyped-def]
    return json.dumps(
        [[t.id, t.subset, t.index, t.instruction, t.task_type, t.payload, t.expert_plan] for t in tasks],
        sort_keys=True,
    )


def test_expert_plans_succeed_on_every_generated_task() -> None:
    env = ADAPTER.make_env("twin", images=False)
    for subset in ADAPTER.subsets:
        tasks = ADAPTER.generate_tasks(0, subset, N)
        assert len(tasks) == N
        for task in tasks:
            env.reset(task)
            assert task.expert_plan and len(task.expert_plan) <= 18
            results = [env.step(env.action_id(a)) for a in task.expert_plan]
            assert results[-1].success and results[-1].end_reason == "success", task.id
            assert not any(r.invalid for r in results), task.id


def test_records_have_embodiedbench_format(eb_data_dir: Path) -> None:
    eb_keys = set(json.loads((eb_data_dir / "eb_navigation" / "base.json").read_text())["tasks"][0])
    for subset in ADAPTER.subsets:
        for i, task in enumerate(ADAPTER.generate_tasks(3, subset, 20)):
            record = task.payload["record"]
            assert set(record) == eb_keys
            validate_record(Path("generated.json"), i, record)  # the loader's own checks pass
            assert record["instruction"] == task.instruction


def test_subsets_share_rooms_and_differ_in_wording() -> None:
    by_subset = {s: ADAPTER.generate_tasks(1, s, 10) for s in ADAPTER.subsets}
    for k in range(10):
        base, lh = by_subset["base"][k], by_subset["long_horizon"][k]
        for tasks in by_subset.values():
            assert tasks[k].payload["scene"] == base.payload["scene"]
            assert tasks[k].payload["record"]["target_position"] == base.payload["record"]["target_position"]
        target_type = base.payload["record"]["targetObjectType"]
        assert (
            base.instruction == f"navigate to the {target_type} in the room and be as close as possible to it"
        )
        assert lh.instruction == base.instruction
        assert target_type not in by_subset["visual_appearance"][k].instruction
        turned = (
            lh.payload["record"]["agentPose"]["rotation"] - base.payload["record"]["agentPose"]["rotation"]
        ) % 360
        assert turned == 180
        rec = base.payload["record"]
        pose = Pose(rec["agentPose"]["position"]["x"], 0.9, rec["agentPose"]["position"]["z"],
                    rec["agentPose"]["rotation"], 0.0)  # fmt: skip
        target = [(rec["targetObjectIds"], target_type, *rec["target_position"].values())]
        assert visible_objects(pose, target)  # outside long_horizon the target starts in view


def test_same_seed_is_byte_identical_and_independent_of_n() -> None:
    first = _dump(ADAPTER.generate_tasks(7, "common_sense", 30))
    generator._episode.cache_clear()
    assert _dump(ADAPTER.generate_tasks(7, "common_sense", 30)) == first
    assert _dump(ADAPTER.generate_tasks(7, "common_sense", 12)) == _dump(
        ADAPTER.generate_tasks(7, "common_sense", 30)[:12]
    )
    assert _dump(ADAPTER.generate_tasks(8, "common_sense", 30)) != first


def test_byte_identical_across_processes() -> None:
    code = (
        "import json; from benchmarks.eb_navigation import ADAPTER;"
        "ts = ADAPTER.generate_tasks(5, 'base', 15);"
        "print(json.dumps([[t.id, t.instruction, t.payload, t.expert_plan] for t in ts], sort_keys=True))"
    )
    outs = []
    for hash_seed in ("1", "2"):
        env = {**os.environ, "PYTHONHASHSEED": hash_seed}
        outs.append(subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, check=True,
                                   capture_output=True, text=True).stdout)  # fmt: skip
    assert outs[0] == outs[1] and outs[0].startswith("[[")


def test_unknown_subset() -> None:
    with pytest.raises(ValueError, match="unknown EB-Navigation subset"):
        ADAPTER.generate_tasks(0, "spatial", 3)
