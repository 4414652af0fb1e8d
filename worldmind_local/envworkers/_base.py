"""What every worker kind shares: the errors, the settings, how a worker builds its env, its setup.

A worker is told *how to build* its env (`EnvSpec`: benchmark, backend kind, options, wrappers), never
handed an env object: a real simulator (a Unity player, a habitat-sim context with its GL state) cannot
be pickled, and must be created in the process that steps it, after that process has its display or
GPU (`worker_env_vars`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from worldmind_local.env import Env

__all__ = [
    "EnvWorkerError",
    "WorkerLost",
    "EnvSpec",
    "WorkerSettings",
    "WorkerKind",
    "FailurePolicy",
    "DEFAULT_TIMEOUTS",
    "resolve_kind",
    "worker_env_vars",
]

log = logging.getLogger("worldmind_local.envworkers")

WorkerKind = Literal["auto", "inline", "process", "ray"]
FailurePolicy = Literal["replay", "error"]

# (step, reset) timeouts in seconds per benchmark: a healthy AI2-THOR or habitat-sim step takes 0.1-2 s,
# a reset loads a scene (5-30 s; the first one also starts the Unity player or the GL context), so a
# call that takes 30x longer is a hang, not a slow step.
DEFAULT_TIMEOUTS: dict[str, tuple[float, float]] = {
    "eb_alfred": (60.0, 300.0),
    "eb_habitat": (60.0, 300.0),
    "eb_navigation": (60.0, 300.0),
}
FALLBACK_TIMEOUTS = (60.0, 300.0)


class EnvWorkerError(RuntimeError):
    """A worker could not finish an env call: its process died or hung past the timeout, and the failure
    policy gave up (policy `error`, restarts used up, or a replay that did not reproduce the episode).
    The message names the worker, the call and the cause; the episode is recorded as an error."""


class WorkerLost(Exception):
    """Internal: a transport lost its worker (died, hung, could not start). The proxy decides, by the
    failure policy, whether it becomes a restart or an `EnvWorkerError`."""


@dataclass(frozen=True)
class EnvSpec:
    """How to build one env, picklable so it can cross to a process or a Ray actor.

    `wrappers` are picklable callables `env -> env` applied in order (a module-level class or a
    `functools.partial` of one), e.g. `StepLatency` in benchmarks of the workers themselves.
    `adapter` is used only when the benchmark is not in the registry (tests with their own adapter).
    """

    benchmark: str
    kind: str = "twin"
    options: dict[str, Any] = field(default_factory=dict)
    wrappers: tuple[Callable[[Any], Any], ...] = ()
    adapter: Any = None

    def build(self) -> Env:
        adapter = self.adapter
        if adapter is None:
            from worldmind_local.registry import BENCHMARKS

            adapter = BENCHMARKS.get(self.benchmark)
        env = adapter.make_env(self.kind, **self.options)
        for wrap in self.wrappers:
            env = wrap(env)
        return env


class WorkerSettings(BaseModel):
    """Where each stream's env lives and what happens when its worker fails (`worldmind run
    --env-workers ... --env-step-timeout ... --env-failure ... --env-worker-option KEY=VALUE`).

    None of this changes a run's results, so none of it is part of the run's identity.
    """

    model_config = ConfigDict(extra="forbid", arbitrary_types_allowed=True)
    kind: WorkerKind = "auto"
    step_timeout: float | None = Field(None, gt=0, description="seconds per step (None: per benchmark)")
    reset_timeout: float | None = Field(None, gt=0, description="seconds per reset (None: per benchmark)")
    start_timeout: float = Field(600.0, gt=0, description="seconds for a worker to build its env")
    failure: FailurePolicy = "replay"
    max_restarts: int = Field(2, ge=0, description="restarts per failed call before the episode errors")
    start_method: Literal["spawn", "forkserver"] = "spawn"
    eager: tuple[str, ...] = Field((), description="observation fields always sent (text, state, image)")
    frame_codec: Literal["array", "png"] = "array"
    displays: tuple[str, ...] = Field((), description="X displays for AI2-THOR 2.1 workers, round robin")
    gpus: tuple[str, ...] = Field((), description="GPU ids for simulator workers, round robin")
    ray_address: str | None = None
    ray_num_cpus: float | None = Field(None, ge=0)
    ray_num_gpus: float | None = Field(None, ge=0)
    ray_resources: dict[str, float] = Field(default_factory=dict)
    wrappers: tuple[Any, ...] = Field((), exclude=True, description="env wrappers (programmatic only)")

    @field_validator("displays", "gpus", "eager", mode="before")
    @classmethod
    def _comma_list(cls, v: Any) -> Any:
        return tuple(p.strip() for p in v.split(",") if p.strip()) if isinstance(v, str) else v

    @field_validator("ray_resources", mode="before")
    @classmethod
    def _resources(cls, v: Any) -> Any:
        """`display:1,accelerator_type:A100:0.5` style strings, as the CLI passes them."""
        if not isinstance(v, str):
            return v
        out: dict[str, float] = {}
        for part in (p.strip() for p in v.split(",") if p.strip()):
            name, _, amount = part.rpartition(":")
            out[name or part] = float(amount) if name else 1.0
        return out

    def timeouts(self, benchmark: str) -> tuple[float, float]:
        step, reset = DEFAULT_TIMEOUTS.get(benchmark, FALLBACK_TIMEOUTS)
        return self.step_timeout or step, self.reset_timeout or max(reset, self.step_timeout or 0.0)


def resolve_kind(kind: str, env_kind: str) -> str:
    """`auto`: the twins step in microseconds, so inline; a real simulator blocks, so a process."""
    if kind == "auto":
        return "process" if env_kind == "embodiedbench" else "inline"
    if kind not in ("inline", "process", "ray"):
        raise ValueError(f"unknown env worker kind {kind!r}; use auto|inline|process|ray")
    return kind


def _env_list(name: str) -> tuple[str, ...]:
    return tuple(p.strip() for p in os.environ.get(name, "").split(",") if p.strip())


def worker_env_vars(spec: EnvSpec, index: int, settings: WorkerSettings, *, ray: bool = False) -> dict[str, str]:
    """Environment variables a worker sets before it builds its env: the per-benchmark setup of the real
    simulators, spread round robin over the displays and GPUs given (options first, then
    `WORLDMIND_DISPLAYS` / `WORLDMIND_GPUS`, then `DISPLAY` / `CUDA_VISIBLE_DEVICES`).

    - EB-ALFRED (AI2-THOR 2.1.0) renders through an X server: `DISPLAY`.
    - EB-Navigation (AI2-THOR 5 CloudRendering, Vulkan) and EB-Habitat (habitat-sim, EGL) render on a
      GPU: `CUDA_VISIBLE_DEVICES` (habitat-sim picks the EGL device of CUDA device 0 of what it sees).
    On Ray the GPUs are Ray's to assign (`ray_num_gpus`), so only the display is set there.
    """
    if spec.kind != "embodiedbench":
        return {}
    out: dict[str, str] = {}
    if spec.benchmark == "eb_alfred":
        displays = settings.displays or _env_list("WORLDMIND_DISPLAYS") or _env_list("DISPLAY")
        if displays:
            out["DISPLAY"] = displays[index % len(displays)]
        elif not ray:
            log.warning("EB-ALFRED worker %d: no X display (set DISPLAY, WORLDMIND_DISPLAYS or "
                        "--env-worker-option displays=:0,:1); AI2-THOR 2.1.0 needs one", index)
    elif spec.benchmark in ("eb_habitat", "eb_navigation") and not ray:
        gpus = settings.gpus or _env_list("WORLDMIND_GPUS") or _env_list("CUDA_VISIBLE_DEVICES")
        if gpus:
            out["CUDA_VISIBLE_DEVICES"] = gpus[index % len(gpus)]
    if spec.benchmark == "eb_habitat":
        out.setdefault("MAGNUM_LOG", "quiet")
        out.setdefault("HABITAT_SIM_LOG", "quiet")
    return out
