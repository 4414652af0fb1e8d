"""WorldMind end to end with the real SmolLM2 (hf backend) as planner, judge, reflector and distiller,
the real all-MiniLM embedder and the EB-Navigation twin (the shortest faithful prompt, so CPU prefill
stays affordable). The episode is cut to a few steps by a thin wrapper so the test takes about a minute;
everything inside a step is the real thing.
"""

from __future__ import annotations

import asyncio
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from worldmind_local.env import StepResult
from worldmind_local.registry import BENCHMARKS

pytestmark = pytest.mark.slow

PROVENANCE = ("benchmark", "subset", "episode", "task_id", "step", "action", "predicted_state", "actual_state",
              "judge_reason", "planner_model", "judge_model", "run_id", "instruction")


class ShortEpisode:
    """The real twin, with the episode ended as a step-limit timeout after `limit` steps."""

    def __init__(self, env: Any, limit: int) -> None:
        self.env, self.limit, self.steps = env, limit, 0
        self.benchmark, self.max_steps, self.max_invalid = env.benchmark, limit, env.max_invalid

    @property
    def actions(self) -> list[str]:
        return self.env.actions

    def reset(self, task: Any) -> Any:
        self.steps = 0
        return self.env.reset(task)

    def step(self, action_id: int) -> StepResult:
        self.steps += 1
        res = self.env.step(action_id)
        if not res.done and self.steps >= self.limit:
            res = replace(res, done=True, end_reason="max_steps")
        return res

    def action_id(self, name: str) -> int:
        return self.env.action_id(name)

    def close(self) -> None:
        self.env.close()


def test_worldmind_episode_with_real_smollm2(tmp_path: Path):
    import datasets

    from models.specs import make_backend
    from worldmind_local.agent.driver import run_episode
    from worldmind_local.memory import Embedder, WorldKnowledgeRepository
    from worldmind_local.methods.base import EpisodeContext
    from worldmind_local.methods.worldmind import WorldMind

    adapter = BENCHMARKS.get("eb_navigation")
    task = adapter.generate_tasks(0, "base", 1)[0]
    backend = make_backend("hf:smollm2-135m-instruct")
    embedder = Embedder()
    memory = WorldKnowledgeRepository(embedder)
    models = dict.fromkeys(("planner", "judge", "reflector", "distiller", "summarizer"), backend)
    method = WorldMind({"top_k": 2, "verify": "every", "max_plan_actions": 2, "planner_max_tokens": 512,
                        "n_shots": 1})
    ctx = EpisodeContext(
        models=models, model_ids=dict.fromkeys(models, backend.model_id), memory=memory, embedder=embedder,
        run_id="smollm2-e2e", seed=0, config=method.config, adapter=adapter,
    )
    env = ShortEpisode(adapter.make_env("twin", images=False), limit=3)

    async def episode() -> Any:
        try:
            outcome = await run_episode(method, task, env, ctx)
            # the runner's commit: embed and add in order (the method never writes memory)
            kept = [memory.add_embedded(e) for e in await memory.embed(outcome.experience)]
            return outcome, kept
        finally:
            await backend.aclose()

    outcome, kept = asyncio.run(episode())
    record, stats = outcome.record, outcome.record.method_stats

    # every env step is recorded, with its action, feedback and progress
    env_steps = [s for s in record.trajectory if s.env_step]
    assert record.steps == len(env_steps) == env.steps >= 1
    assert all(s.feedback.startswith("Last action") for s in env_steps)
    assert record.planner_calls >= 1 and record.tokens["planner"].completion > 0
    # the verifier ran on a real model answer
    assert stats["judge_calls"] >= 1 and record.observation == "description"
    judged = [s for s in record.trajectory if s.judge_verdict is not None]
    assert judged and all(s.actual_state for s in judged)
    # a judged contradiction becomes Process Experience with full provenance
    if stats["judge_mismatches"] and stats["reflections"]:
        process = [e for e in outcome.experience if e.partition == "process"]
        assert process and len(kept) == len(outcome.experience)
        for entry in process:
            for key in PROVENANCE:
                assert getattr(entry, key) not in (None, ""), key
    # the repository reloads with plain datasets and has 384-dim embeddings
    memory.save(tmp_path / "memory")
    ds = datasets.load_from_disk(str(tmp_path / "memory"))
    assert len(ds) == len(memory)
    if len(ds):
        assert len(ds[0]["key_embedding"]) == 384
    assert ds.features["key_embedding"].length == 384
