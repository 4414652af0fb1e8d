"""EB-Habitat: EmbodiedBench's ReplicaCAD rearrangement benchmark (70 high-level skills, six subsets).

`ADAPTER` is what the registry loads (`benchmarks.eb_habitat:ADAPTER`). Parts, one module each:
``scene`` (the apartment and the spatial model), ``actions`` (the 70 skills), ``data`` (episode
loading and validation), ``predicates`` (goal expressions and subgoals), ``twin`` (the symbolic
simulator), ``oracle`` (plans from episode data), ``generator`` (the procedural suite),
``embodiedbench`` (the real EBHabEnv behind the same contract).
"""

from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from typing import Any

from worldmind_local.env import Env, Task, WorkedExample

from .data import SUBSETS, goal_kind, load_episodes, subset_path

__all__ = ["ADAPTER", "HabitatAdapter"]


class HabitatAdapter:
    """`BenchmarkAdapter` for EB-Habitat."""

    name = "eb_habitat"
    subsets: tuple[str, ...] = SUBSETS
    default_top_k = 1  # official configs eb-hab.yaml
    default_n_shots = 10  # official configs eb-hab.yaml
    # EB's evaluator for unusable planner output: "invalid" (one invalid action, no env step; empty plan
    # ends the episode) or "random" (one random action; out-of-range ids go to the env).
    unusable_output = "invalid"
    # EB-Navigation has no language-only mode: its text description stands in for the image for
    # text-only planners. EB-ALFRED/EB-Habitat text planners see no state at all (EB's language_only).
    text_stand_in_for_image = False

    def load_tasks(self, data_dir: Path, subset: str) -> list[Task]:
        """The subset's 50 episodes in EmbodiedBench's order; `expert_plan` is the oracle plan."""
        from .actions import skills_for
        from .oracle import oracle_plan
        from .twin import HabitatTwin

        twin = HabitatTwin(skills_for(data_dir))
        tasks = []
        for episode in load_episodes(Path(data_dir), subset):
            plan = oracle_plan(episode, twin)
            tasks.append(
                Task(
                    id=f"eb_habitat/{subset}/{episode['index']}",
                    benchmark=self.name,
                    subset=subset,
                    index=episode["index"],
                    instruction=episode["instruction"],
                    task_type=goal_kind(episode["goal_preds"]),
                    payload=episode,
                    expert_plan=plan.actions,
                )
            )
        return tasks

    def generate_tasks(self, seed: int, subset: str, n: int) -> list[Task]:
        from .generator import generate_tasks

        return generate_tasks(seed, subset, n)

    def make_env(self, kind: str = "twin", **options: Any) -> Env:
        """`twin` takes `data_dir` (for the data pack's action_space.json); `embodiedbench` takes
        `env_factory`, `resolution`, `exp_name`, `state_abstractor`."""
        if kind == "twin":
            from .twin import HabitatTwin

            unknown = set(options) - {"data_dir"}
            if unknown:
                raise TypeError(f"eb_habitat twin options: data_dir; got {sorted(unknown)}")
            data_dir = options.get("data_dir")
            return HabitatTwin(data_dir=Path(data_dir) if data_dir is not None else None)
        if kind == "embodiedbench":
            from .embodiedbench import EmbodiedBenchHabitatEnv

            return EmbodiedBenchHabitatEnv(**options)
        raise ValueError(f"unknown env kind {kind!r} for eb_habitat; use 'twin' or 'embodiedbench'")

    def has_data(self, data_dir: Path) -> bool:
        return subset_path(Path(data_dir), SUBSETS[0]).is_file()

    def worked_examples(
        self, n: int, *, data_dir: Path | None = None, exclude: Collection[str] = ()
    ) -> list[WorkedExample]:
        """`min(n, pool size)` few-shot examples: oracle plans run on the twin (examples.py)."""
        from benchmarks.eb_habitat.examples import worked_examples

        return worked_examples(n, data_dir=data_dir, exclude=exclude)


ADAPTER = HabitatAdapter()
