"""EB-Navigation: EmbodiedBench's navigation benchmark (AI2-THOR 5) behind WorldMind-Local's contract.

Parts, as in every benchmark folder: `data.py` + `tasks.py` (EmbodiedBench's episodes), `generator.py`
(generated suites), `twin.py` (the symbolic simulator, with `geometry.py`/`scenes.py` for the room,
`observe.py` for the observation text and `render.py` for the top-down image), `expert.py` (the twin's
shortest plans), `greedy.py` (a text-only baseline planner) and `embodiedbench.py` (the wrapper of the
real EBNavigationEnv). Submodules are imported on first use.
"""

from __future__ import annotations

from collections.abc import Collection
from pathlib import Path
from typing import Any

from benchmarks.eb_navigation.data import SUBSETS, has_any_subset
from worldmind_local.env import Env, Task, WorkedExample

__all__ = ["ADAPTER", "NavigationAdapter"]


class NavigationAdapter:
    """`BenchmarkAdapter` for EB-Navigation."""

    name = "eb_navigation"
    subsets: tuple[str, ...] = SUBSETS
    default_top_k = 2  # official configs eb-nav.yaml
    default_n_shots = 3  # official configs eb-nav.yaml
    # EB's evaluator for unusable planner output: "invalid" (one invalid action, no env step; empty plan
    # ends the episode) or "random" (one random action; out-of-range ids go to the env).
    unusable_output = "random"
    # EB-Navigation has no language-only mode: its text description stands in for the image for
    # text-only planners. EB-ALFRED/EB-Habitat text planners see no state at all (EB's language_only).
    text_stand_in_for_image = True

    def load_tasks(self, data_dir: Path, subset: str) -> list[Task]:
        from benchmarks.eb_navigation.tasks import load_tasks

        return load_tasks(Path(data_dir), subset)

    def generate_tasks(self, seed: int, subset: str, n: int) -> list[Task]:
        from benchmarks.eb_navigation.generator import generate_tasks

        if subset not in self.subsets:
            raise ValueError(f"unknown EB-Navigation subset {subset!r}; known: {', '.join(self.subsets)}")
        return generate_tasks(seed, subset, n)

    def make_env(self, kind: str = "twin", **options: Any) -> Env:
        """`twin` (options: images=True, image_size=448) or `embodiedbench` (see embodiedbench.py)."""
        if kind == "twin":
            from benchmarks.eb_navigation.twin import NavigationTwin

            return NavigationTwin(**options)
        if kind == "embodiedbench":
            from benchmarks.eb_navigation.embodiedbench import EmbodiedBenchNavigation

            return EmbodiedBenchNavigation(**options)
        raise ValueError(f"unknown env kind {kind!r} for eb_navigation; use 'twin' or 'embodiedbench'")

    def has_data(self, data_dir: Path) -> bool:
        return has_any_subset(Path(data_dir))

    def worked_examples(
        self, n: int, *, data_dir: Path | None = None, exclude: Collection[str] = ()
    ) -> list[WorkedExample]:
        """`min(n, pool size)` few-shot examples: shortest plans run on the twin (examples.py)."""
        from benchmarks.eb_navigation.examples import worked_examples

        return worked_examples(n, data_dir=data_dir, exclude=exclude)


ADAPTER = NavigationAdapter()
