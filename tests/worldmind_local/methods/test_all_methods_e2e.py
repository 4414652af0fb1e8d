"""Every method of the comparison, end to end: on the three benchmarks through the runner (model-free
backend), resumed after a SIGKILL exactly like an uninterrupted run, and one short episode each with the
real SmolLM2 on every benchmark (concurrently, on one hf backend)."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from worldmind_local.records import EpisodeRecord
from worldmind_local.runner import RunConfig, StreamSpec, run_experiment

COMPARISON = ("react", "bon", "simura", "synapse", "awm", "reasoningbank", "naivemem", "worldmind")
RANDOM = "random:seeded-random"
SMALL_SIMURA = {"policy_samples": 4, "critic_samples": 2, "max_clusters": 2}


def _options(method: str) -> dict[str, Any]:
    return dict(SMALL_SIMURA) if method == "simura" else {}


@pytest.fixture(scope="module")
def embedder():
    from worldmind_local.memory import Embedder

    return Embedder()


@pytest.mark.parametrize("benchmark", ["eb_alfred", "eb_habitat", "eb_navigation"])
def test_every_method_runs_on_every_benchmark(tmp_path: Path, embedder, benchmark: str) -> None:
    streams = [StreamSpec(benchmark=benchmark, subset="base", method=m, planner=RANDOM, limit=2,
                          options=_options(m)) for m in COMPARISON]
    config = RunConfig(streams=streams, suite="generated", suite_size=2)
    result = asyncio.run(run_experiment(config, tmp_path / "run", embedder=embedder, progress=False))
    assert not result.failed, [(o.stream_id, o.error) for o in result.failed]
    for spec in streams:
        lines = (tmp_path / "run" / "streams" / spec.stream_id / "episodes.jsonl").read_text().splitlines()
        records = [EpisodeRecord.model_validate_json(line) for line in lines]
        assert [r.index for r in records] == [0, 1] and all(r.method == spec.method for r in records)
        assert all("key_embedding" not in json.dumps(r.experience) for r in records)
        assert all(any(c.role == "planner" for c in r.calls) for r in records)


VOLATILE = ("latency", "seconds", "_ms", "time")


def _strip(obj: Any) -> Any:
    """Drop wall-clock fields (they differ between any two runs)."""
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if not any(t in k for t in VOLATILE)}
    if isinstance(obj, list):
        return [_strip(v) for v in obj]
    return obj


def _episodes(run: Path) -> dict[str, list[dict]]:
    return {folder.name: [_strip(json.loads(x)) for x in (folder / "episodes.jsonl").read_text().splitlines()]
            for folder in sorted((run / "streams").iterdir())}


def _memories(run: Path) -> dict[str, list[str]]:
    import datasets

    out = {}
    for folder in sorted((run / "streams").iterdir()):
        if (folder / "memory").exists():
            out[folder.name] = [row["id"] for row in datasets.load_from_disk(str(folder / "memory"))]
    return out


@pytest.mark.slow
def test_every_method_resumes_after_sigkill_exactly(tmp_path: Path) -> None:
    specs = tmp_path / "specs"
    specs.mkdir()
    (specs / "slow.yaml").write_text("name: slow-random\nbackend: random\nmodel_id: seeded-random\n"
                                     "weights: {}\noptions: {latency_s: 0.02}\n")
    env = {**os.environ, "WORLDMIND_MODEL_SPECS": str(specs)}

    def command(out: Path) -> list[str]:
        return [sys.executable, "-m", "worldmind_local.cli", "run", "--benchmark", "eb_navigation", "--subsets",
                "base", "--suite", "generated", "--suite-size", "3", "--planner", "random:slow-random",
                "--method", ",".join(COMPARISON), "--policy-samples", "4", "--critic-samples", "2",
                "--max-clusters", "2", "--out", str(out), "--progress", "lines"]

    killed = tmp_path / "killed" / "run"
    proc = subprocess.Popen(command(killed), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 240
    while time.time() < deadline:
        done = sum(len(p.read_text().splitlines()) for p in killed.glob("streams/*/episodes.jsonl"))
        if done >= 6:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert 6 <= done < 3 * len(COMPARISON), "the run finished before it could be killed"
    resumed = subprocess.run(command(killed), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    ref = tmp_path / "ref" / "run"  # the same run id (folder name): it is part of the provenance
    clean = subprocess.run(command(ref), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert clean.returncode == 0, clean.stderr[-3000:]
    assert _episodes(killed) == _episodes(ref)
    assert _memories(killed) == _memories(ref)


@pytest.mark.slow
@pytest.mark.parametrize("benchmark", ["eb_navigation", "eb_alfred", "eb_habitat"])
def test_every_method_with_real_smollm2_on_one_short_episode(tmp_path: Path, embedder, benchmark: str) -> None:
    from models.specs import make_backend
    from worldmind_local.agent.driver import run_episode
    from worldmind_local.methods.base import EpisodeContext
    from worldmind_local.registry import BENCHMARKS, METHODS

    sys.path.insert(0, str(Path(__file__).parent))
    from test_worldmind_smollm2 import ShortEpisode  # type: ignore[import-not-found]

    adapter = BENCHMARKS.get(benchmark)
    task = adapter.generate_tasks(0, "base", 1)[0]
    backend = make_backend("hf:smollm2-135m-instruct")

    async def one(name: str) -> Any:
        # short prompts and answers keep 8 concurrent CPU episodes affordable; the mechanics are the real ones
        # EB-Habitat's WorldMind-format answers need more room than 160 tokens to close their JSON
        budget = 320 if benchmark == "eb_habitat" else 160
        options = {"max_plan_actions": 2, "planner_max_tokens": budget, "n_shots": 0, **_options(name)}
        if name == "bon":
            options.update(n_candidates=3, selector_max_tokens=96)
        if name in ("synapse", "awm", "reasoningbank"):
            options.update(memory_judge_max_tokens=64, success_signal="llm_judge")
        if name == "awm":
            options.update(induction_max_tokens=96)
        if name == "reasoningbank":
            options.update(extraction_max_tokens=96)
        if name == "simura":
            options.update(policy_samples=2, critic_samples=1, policy_max_tokens=96, critic_max_tokens=64,
                           encoder_max_tokens=96, memory_max_tokens=64, world_model_max_tokens=96)
        method = METHODS.get(name)(options)
        memory = method.new_memory(embedder, None)
        ctx = EpisodeContext(models={"planner": backend, "judge": backend}, model_ids={"planner": backend.model_id},
                             memory=memory, embedder=embedder, run_id="smollm2-all", seed=0,
                             config=method.config, adapter=adapter)
        env = ShortEpisode(adapter.make_env("twin"), limit=1)
        outcome = await run_episode(method, task, env, ctx)
        return name, outcome

    async def all_methods() -> list[Any]:
        try:
            return await asyncio.gather(*(one(m) for m in COMPARISON))
        finally:
            await backend.aclose()

    for name, outcome in asyncio.run(all_methods()):
        rec = outcome.record
        assert rec.method == name and rec.error is None, (name, rec.error)
        assert rec.planner_calls >= 1 and rec.tokens["planner"].completion > 0, name
        assert rec.steps == 1 or rec.planner_output_errors > 0, name  # a cut-off answer is EB's invalid output
        assert all(s.feedback.startswith("Last action") for s in rec.trajectory if s.env_step), name


class _ReadOnly:
    """A memory view that fails the test on any write: only the runner may write a stream's memory."""

    WRITES = ("add", "add_embedded", "commit", "save")

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def __getattr__(self, name: str) -> Any:
        if name in self.WRITES:
            raise AssertionError(f"a method wrote its memory ({name})")
        return getattr(self._inner, name)

    def __len__(self) -> int:
        return len(self._inner)


def test_no_method_writes_its_memory(embedder) -> None:
    from models.specs import make_backend
    from worldmind_local.agent.driver import run_episode
    from worldmind_local.methods.base import EpisodeContext
    from worldmind_local.registry import BENCHMARKS, METHODS

    adapter = BENCHMARKS.get("eb_alfred")
    tasks = adapter.generate_tasks(0, "base", 2)
    backend = make_backend(RANDOM)

    async def two_episodes(name: str) -> None:
        method = METHODS.get(name)(_options(name))
        memory = method.new_memory(embedder, None)
        for i, task in enumerate(tasks):
            view = _ReadOnly(memory) if memory is not None else None
            ctx = EpisodeContext(models={"planner": backend, "judge": backend},
                                 model_ids={"planner": backend.model_id}, memory=view, embedder=embedder,
                                 run_id="ro", seed=0, config=method.config, adapter=adapter)
            outcome = await run_episode(method, task, adapter.make_env("twin"), ctx)
            if memory is not None:  # the runner's commit
                for entry in await memory.embed(outcome.experience):
                    memory.add_embedded(entry)
                memory.commit(i)

    async def all_methods() -> None:
        for name in METHODS.names():
            await two_episodes(name)

    asyncio.run(all_methods())
