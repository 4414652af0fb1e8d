"""Ray env workers on a local Ray cluster (`make test-ray`: Ray lives in .venv-ray; starting the cluster
takes ~10 s on 2 cores): the same episodes and memory as inline, and a killed actor is replaced and its
episode replayed."""

from __future__ import annotations

import asyncio
from functools import partial
from pathlib import Path
from typing import Any

import pytest

ray = pytest.importorskip("ray", reason="Ray is an optional extra: make test-ray")

from worldmind_local.envworkers import (  # noqa: E402
    InjectFault,
    WorkerEnv,
    WorkerSettings,
    close_env,
    make_env_worker,
)
from worldmind_local.envworkers._base import EnvSpec  # noqa: E402
from worldmind_local.envworkers._ray import ray_resources_for  # noqa: E402
from worldmind_local.registry import BENCHMARKS  # noqa: E402

pytestmark = pytest.mark.ray

BENCHES = ("eb_alfred", "eb_habitat", "eb_navigation")


@pytest.fixture(scope="module", autouse=True)
def cluster():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, namespace="worldmind")
    yield
    ray.shutdown()


def _helpers() -> Any:
    """The step-by-step and whole-run helpers of the process-worker tests (one definition of each)."""
    import importlib.util

    path = Path(__file__).with_name("test_envworkers.py")
    spec = importlib.util.spec_from_file_location("_envworker_tests", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


H = _helpers()
embedder = H.embedder
inline_run = H.inline_run


@pytest.mark.parametrize("bench", BENCHES)
def test_ray_worker_equals_inline_step_by_step(bench: str):
    async def main() -> None:
        ad = BENCHMARKS.get(bench)
        inline = ad.make_env("twin")
        worker = make_env_worker(ad, "twin", WorkerSettings(kind="ray"))
        assert isinstance(worker, WorkerEnv)
        try:
            for task in H._tasks(bench, 2):
                assert await H._episode(worker, task) == await H._episode(inline, task)
        finally:
            await close_env(worker)

    asyncio.run(main())


def test_a_killed_actor_is_replaced_and_the_episode_replayed(tmp_path: Path):
    task = H._tasks("eb_alfred", 1)[0]
    reference = asyncio.run(H._episode(BENCHMARKS.get("eb_alfred").make_env("twin"), task))
    wrap = partial(InjectFault, marker=str(tmp_path / "fired"), at_step=3, fault="kill")
    worker = make_env_worker(BENCHMARKS.get("eb_alfred"), "twin", WorkerSettings(kind="ray", wrappers=(wrap,)))

    async def main() -> list[Any]:
        try:
            return await H._episode(worker, task)
        finally:
            await worker.aclose()

    assert asyncio.run(main()) == reference
    assert worker.restarts == 1 and (tmp_path / "fired").exists()


def test_a_run_through_ray_workers_equals_the_inline_run(tmp_path: Path, embedder: Any, inline_run: Path):
    out = tmp_path / "run"
    assert not H._run(out, embedder, env_workers="ray").failed
    for spec in H._streams():
        assert H._episodes(out, spec.stream_id) == H._episodes(inline_run, spec.stream_id)
        assert H._memory_rows(out, spec.stream_id) == H._memory_rows(inline_run, spec.stream_id)


def test_resource_requests():
    twin = ray_resources_for(EnvSpec("eb_navigation", "twin"), WorkerSettings())
    assert twin == {"num_cpus": 0.125, "num_gpus": 0.0}
    habitat = ray_resources_for(EnvSpec("eb_habitat", "embodiedbench"),
                                WorkerSettings(ray_resources="display:1", ray_num_cpus=2))
    assert habitat == {"num_cpus": 2, "num_gpus": 0.25, "resources": {"display": 1.0}}
