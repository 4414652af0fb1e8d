"""`manifest.json` and `results.json` as typed models: a run's record can be loaded, validated, diffed.

The runner builds both files through these models (`Manifest.model_validate(...)`, `Results(...)`), so
a field that drifts fails at write time, not in somebody's notebook later. `Results.load(path)` and
`Manifest.load(path)` read them back.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["StreamMetrics", "StreamResult", "TableRow", "Results", "Manifest"]


class StreamMetrics(BaseModel):
    model_config = ConfigDict(extra="forbid")
    episodes: int
    SR: float | None
    SR_ci95: list[float] | None     # Wilson 95% interval of SR (percent); see worldmind_local/metrics.py
    GC: float | None
    GC_ci95: list[float] | None     # percentile bootstrap 95% interval of GC over episodes (percent)
    taxonomy: dict[str, int]
    mean_steps: float | None
    judge_calls: int = 0
    judge_mismatches: int = 0
    judge_unparseable: int = 0
    reflections: int = 0
    tokens_per_reflection: float | None = None
    distillations: int = 0
    tokens_per_distillation: float | None = None
    tokens_total: dict[str, int] = Field(default_factory=dict)
    retrieval_ms_per_step: float | None = None
    observation: list[str] = Field(default_factory=list)
    calls_per_episode: dict[str, float] = Field(default_factory=dict)
    experience_kept: int = 0


class StreamResult(BaseModel):
    """One stream: its spec (flattened, as in StreamSpec), status and metrics."""

    model_config = ConfigDict(extra="forbid")
    stream_id: str
    status: str | None
    error: str | None = None
    benchmark: str
    subset: str
    method: str
    planner: str
    judge: str | None = None
    seed: int = 0
    memory_from: str | None = None
    memory_sha256: str | None = None
    memory_budget: int | None = None
    limit: int | None = None
    options: dict[str, Any] = Field(default_factory=dict)
    perturb: str | None = None            # "rename" | "poison:RATE" (worldmind_local/perturb)
    task_order_seed: int | None = None    # seeded permutation of the episode order
    metrics: StreamMetrics


class TableRow(BaseModel):
    model_config = ConfigDict(extra="forbid")
    benchmark: str
    method: str
    planner: str
    judge: str
    seed: int | None
    options: dict[str, Any] | None
    memory_budget: int | None
    subsets: dict[str, dict[str, Any]]
    avg: dict[str, float | None]
    perturb: str | None = None
    task_order_seed: int | None = None
    memory_from: str | None = None          # seed memory: source model/benchmark#sha256[:8]
    gain: dict[str, float | None] | None = None   # avg minus the from-scratch row's avg


class Results(BaseModel):
    model_config = ConfigDict(extra="forbid")
    run_id: str
    finished_at: str
    streams: list[StreamResult]
    table: list[TableRow]
    memory_sources: dict[str, Any] = Field(default_factory=dict)

    @classmethod
    def load(cls, path: str | Path) -> Results:
        return cls.model_validate_json(Path(path).read_text())


class Manifest(BaseModel):
    """What ran: the config (the identity a resume must match), provenance, and how models were shown
    the benchmark (`protocol`, per stream)."""

    model_config = ConfigDict(extra="forbid")
    run_id: str
    started_at: str
    command: list[str]
    command_line: str
    git_sha: str | None
    packages: dict[str, str]
    data: dict[str, Any]
    protocol: dict[str, Any] = Field(default_factory=dict)
    config: dict[str, Any]
    resumed: list[dict[str, Any]] = Field(default_factory=list)
    models: dict[str, Any] = Field(default_factory=dict)
    memory_sources: dict[str, Any] = Field(default_factory=dict)

    @classmethod
    def load(cls, path: str | Path) -> Manifest:
        return cls.model_validate(json.loads(Path(path).read_text()))
