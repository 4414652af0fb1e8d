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
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

__all__ = ["StreamSpec", "RunConfig", "load_plan_file", "expand_streams", "method_class", "canonical_method",
           "STREAM_REF"]

# RunConfig fields that say how a run executes, not what it computes: outside its identity.
EXECUTION_FIELDS = ("env_workers", "ray_address", "env_step_timeout", "env_failure", "env_worker_options")

STREAM_REF = "stream:"   # memory_from "stream:<id>": seed from another stream of the same run, once it finished


def method_class(name: str) -> Any:
    from worldmind_local.registry import METHODS

    return METHODS.get(name)


def canonical_method(method: str, options: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """(method name, options) in their one spelling: options validated against the method's config,
    only values that differ from the defaults kept, and WorldMind's ablation switches turned into the
    ablation's method name (`worldmind` + goal_experience=false -> `worldmind_process_only`)."""
    cls = method_class(method)
    options = dict(options or {})
    from worldmind_local.methods.worldmind import SWITCHES, WorldMind, canonical_variant

    if isinstance(cls, type) and issubclass(cls, WorldMind):
        switches = {k: bool(options.pop(k, cls.fixed[k])) for k in SWITCHES}
        variant = canonical_variant(switches)
        if variant is None:
            raise ValueError(f"method {method}: switches {switches} name no WorldMind variant; use one of the "
                             f"methods worldmind, worldmind_goal_only, worldmind_process_only, "
                             f"worldmind_no_verifier, worldmind_baseline")
        method, cls = variant, method_class(variant)
    config_class = cls.config_class
    unknown = sorted(set(options) - set(config_class.model_fields))
    if unknown:
        raise ValueError(f"method {method} has no option(s) {', '.join(unknown)}; "
                         f"its options: {', '.join(sorted(config_class.model_fields))}")
    full = config_class(**{**options, **getattr(cls, "fixed", {})})
    defaults = config_class(**getattr(cls, "fixed", {}))
    kept = {k: v for k, v in full.model_dump(mode="json").items()
            if k in options and v != getattr(defaults, k) and k not in getattr(cls, "fixed", {})}
    return method, kept


class StreamSpec(BaseModel):
    model_config = ConfigDict(extra="forbid")
    benchmark: str
    subset: str
    method: str = "worldmind"
    planner: str
    judge: str | None = None  # None -> same as planner
    seed: int = 0
    memory_from: str | None = None
    # What memory_from held when the run was set up (content hash of its rows): the run's identity, so the
    # same repository typed as another path (relative, from another folder, its export) is the same run.
    memory_sha256: str | None = None
    memory_budget: int | None = Field(None, ge=0)
    limit: int | None = Field(None, ge=1)
    options: dict[str, Any] = Field(default_factory=dict)
    # The paper's stress tests (worldmind_local/perturb): "rename" or "poison:RATE" (0 < RATE <= 1), and a
    # seeded permutation of the episode order. Part of the stream id only when set.
    perturb: str | None = None
    task_order_seed: int | None = None

    @field_validator("perturb")
    @classmethod
    def _perturb(cls, v: str | None) -> str | None:
        from worldmind_local.perturb.poison import parse_perturb

        return parse_perturb(v)

    @model_validator(mode="after")
    def _canonical(self) -> StreamSpec:
        method, options = canonical_method(self.method, self.options)
        object.__setattr__(self, "method", method)
        object.__setattr__(self, "options", options)
        if self.memory_from and self.memory_sha256 is None and not self.memory_from.startswith(STREAM_REF):
            from worldmind_local.memory.sources import source_key

            object.__setattr__(self, "memory_sha256", source_key(self.memory_from))
        return self

    @property
    def memory_key(self) -> str | None:
        """How the stream's seed memory enters its identity: its content hash when it could be read, else
        the reference as given (`stream:<id>`, or a path the preflight will reject in one line)."""
        return f"sha256:{self.memory_sha256}" if self.memory_sha256 else self.memory_from

    @property
    def seed_stream(self) -> str | None:
        """The stream of the same run this one seeds from (`memory_from: stream:<id>`), if any."""
        if self.memory_from and self.memory_from.startswith(STREAM_REF):
            return self.memory_from[len(STREAM_REF):]
        return None

    @property
    def judge_spec(self) -> str:
        return self.judge or self.planner

    def method_config(self) -> Any:
        cls = method_class(self.method)
        return cls.config_class(**{**self.options, **getattr(cls, "fixed", {})})

    @property
    def label(self) -> str:
        """How reports name the stream's method: the method, plus any non-default options."""
        if not self.options:
            return self.method
        return self.method + "[" + ",".join(f"{k}={v}" for k, v in sorted(self.options.items())) + "]"

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
        extra["memory_from"] = self.memory_key
        extra.update({k: v for k, v in (("perturb", self.perturb), ("task_order_seed", self.task_order_seed))
                      if v is not None})
        if any(v not in (None, {}) for v in extra.values()):
            base += "." + hashlib.sha256(json.dumps(extra, sort_keys=True).encode()).hexdigest()[:8]
        return re.sub(r"[^A-Za-z0-9._-]+", "_", base)


class RunConfig(BaseModel):
    """Everything that defines a run's results (stored in manifest.json; a resume must match it)."""

    model_config = ConfigDict(extra="forbid")
    streams: list[StreamSpec]
    suite: str | None = None  # None: EmbodiedBench data if present, else generated
    data_dir: str | None = None
    suite_seed: int = 0
    suite_size: int = Field(50, ge=1)
    env: str = "twin"
    wave: int = Field(1, ge=1)
    cache: bool = True
    # Where each stream's env lives (worldmind_local.envworkers). How envs are stepped never changes an
    # episode, so these are execution settings, outside identity(): a run may resume under another kind.
    env_workers: Literal["auto", "inline", "process", "ray"] = "auto"
    ray_address: str | None = None
    env_step_timeout: float | None = Field(None, gt=0)
    env_failure: Literal["replay", "error"] = "replay"
    env_worker_options: dict[str, Any] = Field(default_factory=dict)

    @field_validator("env_worker_options")
    @classmethod
    def _worker_options(cls, v: dict[str, Any]) -> dict[str, Any]:
        from worldmind_local.envworkers import WorkerSettings

        reserved = sorted(set(v) & {"kind", "ray_address", "step_timeout", "failure", "wrappers"})
        if reserved:
            raise ValueError(f"env_worker_options: {', '.join(reserved)} have their own settings "
                             f"(env_workers, ray_address, env_step_timeout, env_failure)")
        WorkerSettings(**v)  # unknown or malformed options fail here, before any work
        return v

    def worker_settings(self) -> Any:
        """The `WorkerSettings` every StreamRunner of this run makes its envs with."""
        from worldmind_local.envworkers import WorkerSettings

        return WorkerSettings(kind=self.env_workers, ray_address=self.ray_address,
                              step_timeout=self.env_step_timeout, failure=self.env_failure,
                              **self.env_worker_options)

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

    @model_validator(mode="after")
    def _seeds_resolve(self) -> RunConfig:
        """Every `stream:<id>` names another stream of this run, and no stream waits on itself."""
        by_id = {s.stream_id: s for s in self.streams}
        for spec in self.streams:
            seen = [spec.stream_id]
            current = spec
            while current.seed_stream is not None:
                if current.seed_stream not in by_id:
                    raise ValueError(f"stream {current.stream_id}: memory_from {current.memory_from} names no "
                                     f"stream of this run; known: {', '.join(by_id)}")
                if current.seed_stream in seen:
                    raise ValueError(f"streams {' -> '.join([*seen, current.seed_stream])} seed from each other")
                seen.append(current.seed_stream)
                current = by_id[current.seed_stream]
        return self

    def identity(self) -> dict[str, Any]:
        """The part of the config a resumed run must share with the original. A seed memory counts by
        its content hash, not by the path typed for it."""
        data = self.model_dump(exclude={"cache", *EXECUTION_FIELDS})
        for stream in data["streams"]:
            if stream.get("memory_sha256"):
                stream.pop("memory_from", None)
            else:
                stream.pop("memory_sha256", None)   # runs without one keep their earlier identity
            for key in ("perturb", "task_order_seed"):   # unset stress tests: runs keep their earlier identity
                if stream.get(key) is None:
                    stream.pop(key, None)
        return data


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
    options: dict[str, Any],
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
            options=_applicable(method, options),
        )
        for subset in subsets
        for method in methods
        for seed in seeds
    ]


def _applicable(method: str, options: dict[str, Any]) -> dict[str, Any]:
    """The options that `method`'s config has (a command may list methods with different configs)."""
    from worldmind_local.methods.worldmind import SWITCHES, WorldMind

    cls = method_class(method)
    fields = set(cls.config_class.model_fields)
    if isinstance(cls, type) and issubclass(cls, WorldMind):
        fields |= set(SWITCHES)
    return {k: v for k, v in options.items() if k in fields}


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
