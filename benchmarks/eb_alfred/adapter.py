"""The EB-ALFRED BenchmarkAdapter: EmbodiedBench's episodes, generated suites and the two envs."""

from __future__ import annotations

import warnings
from collections.abc import Collection
from pathlib import Path
from typing import Any

from benchmarks.eb_alfred.data import SUBSETS, episode, load_pack, pack_dir
from benchmarks.eb_alfred.expert import ExpertError, expert_plan
from benchmarks.eb_alfred.generator import generate_tasks
from benchmarks.eb_alfred.scene import cached_scene
from worldmind_local.env import Env, Task, TaskDataError, WorkedExample

__all__ = ["AlfredAdapter"]


class AlfredAdapter:
    """EB-ALFRED: six subsets of 50 episodes; the twin or EmbodiedBench's EBAlfEnv."""

    name = "eb_alfred"
    subsets: tuple[str, ...] = SUBSETS
    default_top_k = 2  # official configs eb-alf.yaml
    default_n_shots = 10  # official configs eb-alf.yaml
    # EB's evaluator for unusable planner output: "invalid" (one invalid action, no env step; empty plan
    # ends the episode) or "random" (one random action; out-of-range ids go to the env).
    unusable_output = "invalid"
    # EB-Navigation has no language-only mode: its text description stands in for the image for
    # text-only planners. EB-ALFRED/EB-Habitat text planners see no state at all (EB's language_only).
    text_stand_in_for_image = False

    def load_tasks(self, data_dir: Path, subset: str) -> list[Task]:
        pack = load_pack(Path(data_dir))
        if subset not in pack.splits:
            raise TaskDataError(pack.root / "splits.json", subset, f"subset missing (has: {', '.join(pack.splits)})")
        tasks = []
        for index in range(len(pack.splits[subset])):
            key, entry, record, facts = episode(pack, subset, index)
            tasks.append(
                Task(
                    id=f"eb_alfred/{subset}/{index}",
                    benchmark=self.name,
                    subset=subset,
                    index=index,
                    instruction=entry["instruction"],
                    task_type=record["task_type"],
                    payload={"key": key, "record": record, "facts": facts, "split": entry},
                    expert_plan=_expert(key, record, facts),
                )
            )
        return tasks

    def generate_tasks(self, seed: int, subset: str, n: int) -> list[Task]:
        if subset not in self.subsets:
            raise ValueError(f"unknown subset {subset!r} for {self.name}; known: {', '.join(self.subsets)}")
        return generate_tasks(seed, subset, n)

    def make_env(self, kind: str = "twin", **options: Any) -> Env:
        if kind == "twin":
            from benchmarks.eb_alfred.twin import AlfredTwin

            return AlfredTwin(**options)
        if kind == "embodiedbench":
            from benchmarks.eb_alfred.embodiedbench import EmbodiedBenchAlfredEnv

            return EmbodiedBenchAlfredEnv(**options)
        raise ValueError(f"unknown env kind {kind!r} for {self.name}; use 'twin' or 'embodiedbench'")

    def has_data(self, data_dir: Path) -> bool:
        return (pack_dir(Path(data_dir)) / "splits.json").is_file()

    def worked_examples(
        self, n: int, *, data_dir: Path | None = None, exclude: Collection[str] = ()
    ) -> list[WorkedExample]:
        """`min(n, pool size)` few-shot examples: expert plans run on the twin (examples.py)."""
        from benchmarks.eb_alfred.examples import worked_examples

        return worked_examples(n, data_dir=data_dir, exclude=exclude)


_PLANS: dict[str, tuple[object, tuple[str, ...] | None]] = {}


def _expert(key: str, record: dict[str, Any], facts: dict[str, Any]) -> tuple[str, ...] | None:
    """The record's expert plan in EB actions (memoised per task key and record object)."""
    hit = _PLANS.get(key)
    if hit is not None and hit[0] is record:
        return hit[1]
    plan: tuple[str, ...] | None
    try:
        plan = tuple(expert_plan(cached_scene(key, record, facts), record["plan"]["high_pddl"]))
    except ExpertError as exc:
        warnings.warn(f"no expert plan for {key}: {exc}", stacklevel=2)
        plan = None
    _PLANS[key] = (record, plan)
    return plan
