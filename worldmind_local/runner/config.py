"""What a run is: a set of experiment streams plus the shared settings (models, cache, concurrency).

An experiment stream = (benchmark, subset, method, planner, judge, seed, initial memory) running its
episodes in order with one evolving memory: the paper's sequential online protocol. `worldmind run`
builds the streams as the product of its comma lists; `--plan experiments.yaml` lists them freely.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

__all__ = ["MethodOptions", "StreamSpec", "RunConfig", "load_plan_file", "expand_streams"]


class MethodOptions(BaseModel):
    """Ablation switches and knobs passed to the method (see methods.base.MethodConfig)."""

    model_config = ConfigDict(extra="forbid")
    top_k: int | None = None
    goal_experience: bool = True
    process_experience: bool = True
    verifier: bool = True
    verify: str = "first"
    abstract_with: str = "text"
    # Sampling caps (None = the method's default; see methods.base.MethodConfig).
    max_plan_actions: int | None = None
    planner_max_tokens: int | None = None
    judge_max_tokens: int | None = None
    reflector_max_tokens: int | None = None
    distiller_max_tokens: int | None = None

    def method_config_fields(self) -> dict[str, Any]:
        """The options as MethodConfig keyword arguments (unset caps left to the method's defaults)."""
        return {k: v for k, v in self.model_dump().items() if v is not None}

    @field_validator("verify")
    @classmethod
    def _verify(cls, v: str) -> str:
        if v not in ("first", "every"):
            raise ValueError("verify must be 'first' or 'every'")
        return v

    @field_validator("top_k")
    @classmethod
    def _top_k(cls, v: int | None) -> int | None:
        if v is not None and v < 0:
            raise ValueError("top_k must be >= 0")
        return v


class StreamSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    benchmark: str
    subset: str
    method: str = "worldmind"
    planner: str
    judge: str | None = None  # None -> same as planner
    seed: int = 0
    memory_from: str | None = None
    memory_budget: int | None = None
    limit: int | None = None
    options: MethodOptions = Field(default_factory=MethodOptions)

    @property
    def judge_spec(self) -> str:
        return self.judge or self.planner

    @property
    def stream_id(self) -> str:
        """Readable and unique: benchmark-subset-method-planner-judge-seed, plus a short hash of the rest."""
        def short(spec: str) -> str:
            return spec.split(":", 1)[-1]

        base = f"{self.benchmark}.{self.subset}.{self.method}.{short(self.planner)}"
        if self.judge_spec != self.planner:
            base += f".j-{short(self.judge_spec)}"
        base += f".s{self.seed}"
        extra = self.model_dump(include={"memory_from", "memory_budget", "options"})
        if extra != StreamSpec(benchmark="x", subset="x", planner="x").model_dump(
            include={"memory_from", "memory_budget", "options"}
        ):
            base += "." + hashlib.sha256(json.dumps(extra, sort_keys=True).encode()).hexdigest()[:8]
        return re.sub(r"[^A-Za-z0-9._-]+", "_", base)


class RunConfig(BaseModel):
    """Everything that defines a run's results (stored in manifest.json; a resume must match it)."""

    model_config = ConfigDict(extra="forbid")
    streams: list[StreamSpec]
    suite: str | None = None  # None: EmbodiedBench data if present, else generated
    data_dir: str | None = None
    suite_seed: int = 0
    suite_size: int = 50
    env: str = "twin"
    wave: int = 1
    cache: bool = True

    @field_validator("wave")
    @classmethod
    def _wave(cls, v: int) -> int:
        if v < 1:
            raise ValueError("wave must be >= 1")
        return v

    @field_validator("streams")
    @classmethod
    def _unique(cls, v: list[StreamSpec]) -> list[StreamSpec]:
        if not v:
            raise ValueError("a run needs at least one stream")
        ids = [s.stream_id for s in v]
        dupes = sorted({i for i in ids if ids.count(i) > 1})
        if dupes:
            raise ValueError(f"duplicate streams: {', '.join(dupes)}")
        return v

    def identity(self) -> dict[str, Any]:
        """The part of the config a resumed run must share with the original."""
        return self.model_dump(exclude={"cache"})


def split_list(value: str | None) -> list[str]:
    return [p.strip() for p in (value or "").split(",") if p.strip()]


def expand_streams(
    *,
    benchmark: str,
    subsets: list[str],
    methods: list[str],
    planner: str,
    judge: str | None,
    seeds: list[int],
    memory_from: str | None,
    memory_budget: int | None,
    limit: int | None,
    options: MethodOptions,
) -> list[StreamSpec]:
    """The product subsets x methods x seeds, in that order (which is also the order of results)."""
    return [
        StreamSpec(
            benchmark=benchmark,
            subset=subset,
            method=method,
            planner=planner,
            judge=judge,
            seed=seed,
            memory_from=memory_from,
            memory_budget=memory_budget,
            limit=limit,
            options=options,
        )
        for subset in subsets
        for method in methods
        for seed in seeds
    ]


def load_plan_file(path: str | Path) -> tuple[dict[str, Any], list[StreamSpec]]:
    """An experiment file:

    ```yaml
    defaults: {benchmark: eb_alfred, planner: hf:smollm2-135m-instruct, limit: 4}
    run: {suite: generated, wave: 1}          # optional RunConfig fields
    streams:
      - {subset: base, method: worldmind}
      - {subset: base, method: worldmind, options: {goal_experience: false}}
      - {subsets: [common_sense, spatial], seeds: [0, 1]}   # lists expand to several streams
    ```
    """
    path = Path(path)
    try:
        raw = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read experiment file: {exc}") from exc
    if not isinstance(raw, dict) or not isinstance(raw.get("streams"), list):
        raise ValueError(f"{path}: field 'streams': expected a list of stream entries")
    defaults = raw.get("defaults") or {}
    run = raw.get("run") or {}
    if not isinstance(defaults, dict) or not isinstance(run, dict):
        raise ValueError(f"{path}: fields 'defaults' and 'run' must be mappings")
    streams: list[StreamSpec] = []
    for i, entry in enumerate(raw["streams"]):
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: field 'streams[{i}]': expected a mapping")
        merged = {**defaults, **entry}
        if isinstance(defaults.get("options"), dict) and isinstance(entry.get("options"), dict):
            merged["options"] = {**defaults["options"], **entry["options"]}
        lists = {
            "subset": merged.pop("subsets", None),
            "method": merged.pop("methods", None),
            "seed": merged.pop("seeds", None),
        }
        combos: list[dict[str, Any]] = [merged]
        for key, values in lists.items():
            if values is None:
                continue
            if not isinstance(values, list):
                raise ValueError(f"{path}: field 'streams[{i}].{key}s': expected a list")
            combos = [{**c, key: v} for c in combos for v in values]
        for combo in combos:
            try:
                streams.append(StreamSpec(**combo))
            except ValidationError as exc:
                raise ValueError(f"{path}: field 'streams[{i}]': {exc}") from exc
    return run, streams
