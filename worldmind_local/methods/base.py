"""The method seam: what the runner hands a method per episode, and what it gets back.

A method is the policy around the planner (prompting, parsing, reacting to steps and episode ends).
The runner builds one `EpisodeContext` per episode: the backends per role, the stream's memory (or a
snapshot of it when episodes run in waves), the embedder, and the `MethodConfig` of the stream.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, Literal, Protocol, runtime_checkable

from models.base import ChatBackend
from worldmind_local.env import Env, Task
from worldmind_local.records import EpisodeRecord

if TYPE_CHECKING:  # the memory package pulls in numpy/datasets; methods import it only when used
    from worldmind_local.memory import Embedder, WorldKnowledgeRepository

__all__ = ["MethodConfig", "EpisodeContext", "Method"]


@dataclass
class MethodConfig:
    """Switches and sampling of one stream. The defaults are full WorldMind with greedy decoding.

    `top_k` None means the benchmark's default (the runner fills it from the adapter). `verify` picks
    predict-act-verify on the first executed action of each plan (the paper) or on every executed
    action. `abstract_with="vlm"` asks a summarizer model to abstract states from images where the env
    gives them. `planner_images` None sends the observation image to the planner exactly when the env
    gives one and the planner backend is a vision-language model.
    """

    top_k: int | None = None
    goal_experience: bool = True
    process_experience: bool = True
    verifier: bool = True
    verify: Literal["first", "every"] = "first"
    abstract_with: Literal["text", "vlm"] = "text"
    max_plan_actions: int = 20
    max_rules: int = 3
    planner_images: bool | None = None
    temperature: float = 0.0
    planner_max_tokens: int = 2048  # fits the bounded schema: 20 actions of bounded strings
    judge_max_tokens: int = 256
    reflector_max_tokens: int = 512
    distiller_max_tokens: int = 512
    summarizer_max_tokens: int = 384

    def __post_init__(self) -> None:
        if self.verify not in ("first", "every"):
            raise ValueError(f"MethodConfig.verify must be 'first' or 'every', not {self.verify!r}")
        if self.abstract_with not in ("text", "vlm"):
            raise ValueError(f"MethodConfig.abstract_with must be 'text' or 'vlm', not {self.abstract_with!r}")
        if self.top_k is not None and self.top_k < 0:
            raise ValueError(f"MethodConfig.top_k must be >= 0, not {self.top_k}")
        if self.max_plan_actions < 1 or self.max_rules < 1:
            raise ValueError("MethodConfig.max_plan_actions and max_rules must be >= 1")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class EpisodeContext:
    models: dict[str, ChatBackend]          # role -> backend: planner, judge, reflector, distiller, summarizer
    model_ids: dict[str, str]               # role -> model id (provenance)
    memory: WorldKnowledgeRepository | None
    embedder: Embedder | None
    run_id: str = ""
    seed: int = 0
    config: MethodConfig = field(default_factory=MethodConfig)


@runtime_checkable
class Method(Protocol):
    name: str

    async def run_episode(self, task: Task, env: Env, ctx: EpisodeContext) -> EpisodeRecord: ...
