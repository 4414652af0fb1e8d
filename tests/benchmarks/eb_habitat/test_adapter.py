"""The EB-Habitat adapter behind the registry: tasks, suites, envs."""

from __future__ import annotations

import pytest

from benchmarks.eb_habitat import ADAPTER
from benchmarks.eb_habitat.twin import HabitatTwin
from worldmind_local.data import load_suite
from worldmind_local.env import BenchmarkAdapter
from worldmind_local.registry import BENCHMARKS


def test_registered_adapter_fits_the_protocol():
    adapter = BENCHMARKS.get("eb_habitat")
    assert adapter is ADAPTER and isinstance(adapter, BenchmarkAdapter)
    assert adapter.subsets == (
        "base",
        "common_sense",
        "complex_instruction",
        "spatial_relationship",
        "visual_appearance",
        "long_horizon",
    )
    assert adapter.default_top_k == 1


@pytest.mark.embodiedbench_data
def test_has_data(eb_data_dir, tmp_path):
    assert ADAPTER.has_data(eb_data_dir) and not ADAPTER.has_data(tmp_path)


@pytest.mark.embodiedbench_data
def test_loaded_tasks_carry_ids_payloads_and_working_plans(eb_data_dir):
    tasks = ADAPTER.load_tasks(eb_data_dir, "complex_instruction")
    assert [t.index for t in tasks] == list(range(50))
    assert tasks[5].id == "eb_habitat/complex_instruction/5" and tasks[5].benchmark == "eb_habitat"
    assert tasks[5].payload["instruction"] == tasks[5].instruction
    env = ADAPTER.make_env("twin", data_dir=eb_data_dir)
    env.reset(tasks[5])
    assert [env.step(env.action_id(a)) for a in tasks[5].expert_plan][-1].success


def test_generated_suite_without_data(tmp_path, monkeypatch):
    monkeypatch.setenv("WORLDMIND_DATA", str(tmp_path))
    suite = load_suite("eb_habitat")
    assert suite.kind == "generated"
    tasks = suite.tasks("visual_appearance")
    assert len(tasks) == 50 and all(t.expert_plan for t in tasks)


def test_make_env_kinds():
    assert isinstance(ADAPTER.make_env(), HabitatTwin)
    with pytest.raises(ValueError, match="unknown env kind"):
        ADAPTER.make_env("unity")
    with pytest.raises(TypeError, match="data_dir"):
        ADAPTER.make_env("twin", resolution=3)
