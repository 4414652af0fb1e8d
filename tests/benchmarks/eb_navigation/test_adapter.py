"""EB-Navigation through the shared seams: registry, BenchmarkAdapter protocol, suite resolution."""

from __future__ import annotations

from pathlib import Path

from benchmarks.eb_navigation import ADAPTER
from worldmind_local.data import load_suite
from worldmind_local.env import BenchmarkAdapter, Env
from worldmind_local.registry import BENCHMARKS


def test_registered_adapter_implements_the_protocol() -> None:
    adapter = BENCHMARKS.get("eb_navigation")
    assert adapter is ADAPTER and isinstance(adapter, BenchmarkAdapter)
    assert adapter.name == "eb_navigation" and adapter.default_top_k == 2
    assert adapter.subsets == (
        "base",
        "common_sense",
        "complex_instruction",
        "visual_appearance",
        "long_horizon",
    )
    assert isinstance(adapter.make_env("twin"), Env)


def test_suites(tmp_path: Path, eb_data_dir: Path) -> None:
    real = load_suite("eb_navigation", data_dir=eb_data_dir)
    assert real.kind == "embodiedbench" and len(real.tasks("visual_appearance")) == 60
    generated = load_suite("eb_navigation", data_dir=None, suite="generated", seed=2, n_per_subset=5)
    tasks = generated.tasks("long_horizon")
    assert len(tasks) == 5 and all(t.expert_plan for t in tasks)
    assert all(t.benchmark == "eb_navigation" and t.subset == "long_horizon" for t in tasks)
