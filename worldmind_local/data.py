"""Where EmbodiedBench task data lives, and which task suite a command runs on."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from worldmind_local.env import BenchmarkAdapter, Task
from worldmind_local.registry import BENCHMARKS

__all__ = ["default_data_dir", "resolve_data_dir", "Suite", "load_suite", "adapter"]

DATA_ENV_VAR = "WORLDMIND_DATA"


def default_data_dir() -> Path:
    """`$WORLDMIND_DATA`, then `~/.cache/worldmind/embodiedbench`."""
    env = os.environ.get(DATA_ENV_VAR)
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "worldmind" / "embodiedbench"


def resolve_data_dir(data_dir: str | Path | None) -> Path:
    return Path(data_dir).expanduser() if data_dir else default_data_dir()


def adapter(benchmark: str) -> BenchmarkAdapter:
    return BENCHMARKS.get(benchmark)


@dataclass(frozen=True)
class Suite:
    """A task suite: EmbodiedBench's own episodes (from a data dir) or a generated one (from a seed)."""

    benchmark: str
    kind: str  # "embodiedbench" | "generated"
    data_dir: Path | None = None
    seed: int = 0
    n_per_subset: int = 50

    def describe(self) -> str:
        if self.kind == "generated":
            return f"{self.benchmark} generated suite (seed {self.seed}, {self.n_per_subset} per subset)"
        return f"{self.benchmark} EmbodiedBench tasks from {self.data_dir}"

    def tasks(self, subset: str) -> list[Task]:
        ad = adapter(self.benchmark)
        if subset not in ad.subsets:
            raise ValueError(
                f"unknown subset {subset!r} for {self.benchmark}; known: {', '.join(ad.subsets)}"
            )
        if self.kind == "generated":
            return ad.generate_tasks(self.seed, subset, self.n_per_subset)
        assert self.data_dir is not None
        return ad.load_tasks(self.data_dir, subset)


def load_suite(
    benchmark: str,
    *,
    data_dir: str | Path | None = None,
    suite: str | None = None,
    seed: int = 0,
    n_per_subset: int = 50,
) -> Suite:
    """Pick the suite. `suite=None` means: EmbodiedBench data if it is present, else the generated one.

    An explicit `--data-dir` that holds no data for the benchmark is an error (never a silent fallback).
    """
    ad = adapter(benchmark)
    if suite not in (None, "embodiedbench", "generated"):
        raise ValueError(f"unknown suite {suite!r}; use 'embodiedbench' or 'generated'")
    if suite == "generated":
        return Suite(benchmark, "generated", seed=seed, n_per_subset=n_per_subset)
    path = resolve_data_dir(data_dir)
    if ad.has_data(path):
        return Suite(benchmark, "embodiedbench", data_dir=path)
    if suite == "embodiedbench" or data_dir is not None:
        raise FileNotFoundError(
            f"no {benchmark} data under {path} (expected the layout of EmbodiedBench's data pack, "
            f"e.g. {path / benchmark}); pass --data-dir DIR or --suite generated"
        )
    return Suite(benchmark, "generated", seed=seed, n_per_subset=n_per_subset)
