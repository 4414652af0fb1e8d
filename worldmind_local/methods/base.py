"""The method seam: what a method is, what it is handed per episode, and what it hands back.

A method is the policy around the planner. The generic episode driver (`worldmind_local.agent.driver`)
implements EmbodiedBench's evaluator protocol once (plan, screen ids, execute until the first invalid
action or the plan's end, re-plan with the history, the step and invalid-action limits, the
benchmark's unusable-output policy) and calls a method's hooks at four points:

- `start(ep)`      once, after `env.reset` (retrieve what the episode needs, load examples);
- `plan(ep)`       once per planning step: build the planner's prompt, ask, parse -> `Proposal`;
- `after_step(ep, check)` after every executed action (collect what to verify);
- `after_plan(ep)` after the actions of one plan ran (verify, reflect);
- `finish(ep)`     once, at the end (distil, judge success for a memory write).

A method never writes to a memory: it appends `ExperienceEntry`s to `ep.experience`, and the runner
commits them to the stream's memory after the episode (in waves: in episode order). A method reads the
committed memory through `ep.ctx.memory`. Each method has one pydantic config (`config_class`) from
which `worldmind run` flags and experiment-file `options` are generated.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field

from models.base import ChatBackend, ChatResult

if TYPE_CHECKING:  # the memory package pulls in numpy/datasets; methods import it only when used
    from worldmind_local.agent.driver import Episode, ExecutedAction
    from worldmind_local.agent.plan import Plan
    from worldmind_local.env import BenchmarkAdapter
    from worldmind_local.memory import Embedder

__all__ = [
    "MethodConfig",
    "EpisodeContext",
    "Proposal",
    "Method",
    "BaseMethod",
    "MemoryScope",
    "ObservationMode",
]

ObservationMode = Literal["auto", "image", "none", "symbolic"]
MemoryScope = Literal["episodic", "global"]


class MethodConfig(BaseModel):
    """Settings every method has. Subclasses add their own fields; every field is a CLI flag.

    `observation` says what the planner is shown of the current state (EB's protocol by default):
    `auto` = the camera image for a vision planner where the env renders one; otherwise EB's
    language-only mode (`none`: instruction, actions, examples, history with feedback) on EB-ALFRED and
    EB-Habitat, and EB-Navigation's text description as the stand-in for its image. `symbolic` shows
    the twin's perfect abstract state: an explicit, labelled departure from the benchmark.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    observation: ObservationMode = Field("auto", description="what the planner sees: auto|image|none|symbolic")
    n_shots: int | None = Field(None, ge=0, le=20, description="in-context examples (default per benchmark)")
    temperature: float = Field(0.0, ge=0.0, le=2.0, description="planner sampling temperature")
    max_plan_actions: int = Field(20, ge=1, le=20, description="cap on actions per plan (paper: 20)")
    planner_max_tokens: int = Field(2048, ge=16, le=32768, description="planner token budget")


@dataclass
class EpisodeContext:
    """What the runner hands a method for one episode. `memory` is the committed memory of the stream
    (or of the wave's snapshot): read it, never write it."""

    models: dict[str, ChatBackend]          # role -> backend
    model_ids: dict[str, str]               # role -> model id (provenance)
    memory: Any | None
    embedder: Embedder | None
    run_id: str = ""
    seed: int = 0
    config: MethodConfig = field(default_factory=MethodConfig)
    adapter: BenchmarkAdapter | None = None
    data_dir: str | None = None


@dataclass
class Proposal:
    """One planning step's answer: the parsed plan, or why there is none (`error`: EB's
    output_json_error). `result` is the planner call's result (tokens, latency); `extra` goes into the
    step's PlanRecord (what the method retrieved, selected, scored)."""

    plan: Plan | None
    result: ChatResult | None = None
    raw: str = ""
    error: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class Method(Protocol):
    name: ClassVar[str]
    description: ClassVar[str]
    memory_scope: ClassVar[MemoryScope]
    config_class: ClassVar[type[MethodConfig]]
    config: MethodConfig

    def new_memory(self, embedder: Any, budget: int | None) -> Any | None: ...

    def load_memory(self, path: str, embedder: Any, budget: int | None) -> Any | None: ...

    async def start(self, ep: Episode) -> None: ...

    async def plan(self, ep: Episode) -> Proposal: ...

    def after_step(self, ep: Episode, executed: ExecutedAction) -> None: ...

    async def after_plan(self, ep: Episode) -> None: ...

    async def finish(self, ep: Episode) -> None: ...


class BaseMethod:
    """No-op hooks and the config plumbing; a method overrides what it needs."""

    name: ClassVar[str] = "base"
    description: ClassVar[str] = ""
    memory_scope: ClassVar[MemoryScope] = "episodic"
    config_class: ClassVar[type[MethodConfig]] = MethodConfig
    # Fields a named variant fixes (an ablation is a method name, never a flag).
    fixed: ClassVar[dict[str, Any]] = {}

    def __init__(self, config: MethodConfig | dict[str, Any] | None = None) -> None:
        if isinstance(config, MethodConfig):
            config = config.model_dump(exclude_unset=True)
        self.config = self.config_class(**{**(config or {}), **self.fixed})

    def new_memory(self, embedder: Any, budget: int | None) -> Any | None:
        return None

    def load_memory(self, path: str, embedder: Any, budget: int | None) -> Any | None:
        return None

    async def start(self, ep: Episode) -> None:
        return None

    async def plan(self, ep: Episode) -> Proposal:  # pragma: no cover - every method plans
        raise TypeError(f"method {self.name} does not implement plan()")

    def after_step(self, ep: Episode, executed: ExecutedAction) -> None:
        return None

    async def after_plan(self, ep: Episode) -> None:
        return None

    async def finish(self, ep: Episode) -> None:
        return None
