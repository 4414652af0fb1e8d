"""WorldMind and its ablations as Methods.

The ablations are the same loop with switches turned off (paper Sec. "Ablation Study" and the
controlled memory ablation): without Goal Experience, without Process Experience, without the
verifier (no judge calls, hence no Process Experience either), and the "Baseline" row that keeps the
WorldMind prompt framework with every memory and verification component off. A switch set on the
method wins over the stream's MethodConfig; everything else comes from the stream.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, ClassVar

from worldmind_local.agent.loop import EpisodeLoop
from worldmind_local.env import Env, Task
from worldmind_local.methods.base import EpisodeContext
from worldmind_local.records import EpisodeRecord

__all__ = [
    "WorldMind",
    "WorldMindMethod",
    "WorldMindNoGoal",
    "WorldMindNoProcess",
    "WorldMindNoVerifier",
    "WorldMindBaseline",
    "WorldMindVerifyEvery",
    "ABLATIONS",
]


class WorldMind:
    name: ClassVar[str] = "worldmind"
    overrides: ClassVar[dict[str, Any]] = {}

    def __init__(self, **overrides: Any) -> None:
        self.switches = {**type(self).overrides, **overrides}

    async def run_episode(self, task: Task, env: Env, ctx: EpisodeContext) -> EpisodeRecord:
        if self.switches:
            ctx = replace(ctx, config=replace(ctx.config, **self.switches))
        return await EpisodeLoop(task, env, ctx, method=self.name).run()


class WorldMindNoGoal(WorldMind):
    name = "worldmind_no_goal"
    overrides = {"goal_experience": False}


class WorldMindNoProcess(WorldMind):
    name = "worldmind_no_process"
    overrides = {"process_experience": False}


class WorldMindNoVerifier(WorldMind):
    name = "worldmind_no_verifier"
    overrides = {"verifier": False}


class WorldMindBaseline(WorldMind):
    """The WorldMind prompt framework with memory and verification off (the controlled ablation's Baseline)."""

    name = "worldmind_baseline"
    overrides = {"goal_experience": False, "process_experience": False, "verifier": False}


class WorldMindVerifyEvery(WorldMind):
    name = "worldmind_verify_every"
    overrides = {"verify": "every"}


WorldMindMethod = WorldMind  # the name worldmind_local.registry's METHODS entry points at

ABLATIONS: dict[str, type[WorldMind]] = {
    cls.name: cls
    for cls in (WorldMind, WorldMindNoGoal, WorldMindNoProcess, WorldMindNoVerifier, WorldMindBaseline,
                WorldMindVerifyEvery)
}
