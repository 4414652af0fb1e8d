"""Helpers: synthetic run folders with chosen outcomes (exact numbers for table tests)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest


def _record(i: int, success: bool, progress: float, **extra: Any) -> dict[str, Any]:
    rec = {"task_id": f"t{i}", "index": i, "instruction": f"do task {i}", "task_type": "pick", "success": success,
           "progress": progress, "taxonomy": "success" if success else extra.pop("taxonomy", "step_limit"),
           "steps": 4, "tokens": {"planner": {"prompt": 100, "completion": 10},
                                  "reflector": {"prompt": 30, "completion": 10}},
           "method_stats": {"reflections": 1}, "calls": [{"key": "planner:0", "role": "planner", "request": "x"}],
           "retrieval_seconds": [0.004], "experience": [], "plans": [], "trajectory": []}
    rec.update(extra)
    return rec


def write_run(root: Path, streams: list[dict[str, Any]], env: str = "twin") -> Path:
    """streams: [{"spec": {...StreamSpec fields...}, "outcomes": [(success, progress), ...]}]."""
    from worldmind_local.runner.config import StreamSpec

    root.mkdir(parents=True)
    results, config, data = [], [], {}
    for item in streams:
        spec = StreamSpec(**item["spec"])
        sid = spec.stream_id
        folder = root / "streams" / sid
        folder.mkdir(parents=True)
        recs = [_record(i, s, p) for i, (s, p) in enumerate(item["outcomes"])]
        (folder / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
        results.append({"stream_id": sid, "status": "finished", **spec.model_dump(mode="json")})
        config.append(spec.model_dump(mode="json"))
        data[sid] = {"suite": "eb_alfred generated suite (seed 0, 4 per subset)", "episodes": len(recs)}
    (root / "manifest.json").write_text(json.dumps({"run_id": root.name, "config": {"env": env, "streams": config},
                                                   "data": data, "command_line": "worldmind run ..."}))
    (root / "results.json").write_text(json.dumps({"run_id": root.name, "streams": results, "table": []}))
    return root


@pytest.fixture()
def make_run(tmp_path: Path):
    def make(name: str, streams: list[dict[str, Any]], env: str = "twin") -> Path:
        return write_run(tmp_path / name, streams, env)

    return make


# -- real runs (random:seeded-random on the EB-ALFRED twin), shared by the end-to-end and browser tests --

RANDOM = "random:seeded-random"


def _spec(subset: str, method: str = "worldmind", seed: int = 0, **kw: Any) -> Any:
    from worldmind_local.runner.config import StreamSpec

    return StreamSpec(benchmark="eb_alfred", subset=subset, method=method, planner=RANDOM, seed=seed, limit=3, **kw)


@pytest.fixture(scope="session")
def real_runs(tmp_path_factory) -> dict[str, Path]:
    """Three runs: A and B = two methods x two subsets, seeds 0 and 1; C = a transfer from A's memory plus
    the stress tests (rename, poison:0.2, two task orders) and a memory-budget / top-k sweep taken
    from examples/memory_budget.yaml."""
    import asyncio

    from worldmind_local.memory import Embedder
    from worldmind_local.runner import RunConfig, run_experiment
    from worldmind_local.runner.config import load_plan_file

    embedder = Embedder()
    root = tmp_path_factory.mktemp("real")
    runs = {}

    def run(name: str, streams: list[Any]) -> Path:
        config = RunConfig(streams=streams, suite="generated", suite_size=3)
        result = asyncio.run(run_experiment(config, root / name, embedder=embedder, progress=False))
        assert not result.failed, [o.error for o in result.failed]
        return root / name

    for name, seed in (("runA", 0), ("runB", 1)):
        runs[name] = run(name, [_spec(sub, m, seed) for m in ("worldmind", "react")
                                for sub in ("base", "common_sense")])
    source = runs["runA"] / "streams" / _spec("common_sense").stream_id / "memory"
    _, budget = load_plan_file(REPO / "examples" / "memory_budget.yaml")
    sweep = [_spec("base", memory_budget=s.memory_budget, options=s.options) for s in budget
             if s.subset == "base" and s.memory_budget in (0, 10, 30)]
    runs["runC"] = run("runC", [
        _spec("base", memory_from=str(source)),
        _spec("base", perturb="rename"), _spec("base", "react", perturb="rename"),
        _spec("base", memory_from=str(source), perturb="poison:0.2"),
        _spec("base", task_order_seed=1), _spec("base", task_order_seed=2),
        *sweep,
    ])
    return runs


REPO = Path(__file__).resolve().parents[3]
