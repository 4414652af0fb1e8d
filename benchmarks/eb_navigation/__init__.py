"""EB-Navigation: EmbodiedBench's navigation benchmark (AI2-THOR 5) behind WorldMind-Local's contract.

Parts, as in every benchmark folder: `data.py` + `tasks.py` (EmbodiedBench's episodes), `generator.py`
(generated suites), `twin.py` (the symbolic simulator, with `geometry.py`/`scenes.py` for the room,
`observe.py` for the observation text and `render.py` for the top-down image), `expert.py` (the twin's
shortest plans), `greedy.py` (a text-only baseline planner) and `embodiedbench.py` (the wrapper of the
real EBNavigationEnv). Submodules are imported on first use.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from benchmarks.eb_navigation.data import SUBSETS, has_any_subset
from worldmind_local.env import Env, Task

__all__ = ["ADAPTER", "NavigationAdapter"]


class NavigationAdapter:
    """`BenchmarkAdapter` for EB-Navigation."""

    name = "eb_navigation"
    subsets: tuple[str, ...] = SUBSETS
    default_top_k = 2

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


ADAPTER = NavigationAdapter()
