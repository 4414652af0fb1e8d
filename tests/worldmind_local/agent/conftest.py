"""Scripted stand-ins for the agent tests: a backend that answers from a script per role, a tiny
apple-into-fridge world that speaks EmbodiedBench's feedback style, and a deterministic embedder."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from models.base import ChatRequest, ChatResult, ContextLengthError
from worldmind_local.agent.driver import run_episode
from worldmind_local.env import Observation, StepResult, Task
from worldmind_local.memory import Embedder, WorldKnowledgeRepository
from worldmind_local.methods.base import EpisodeContext
from worldmind_local.methods.worldmind import WorldMind, WorldMindConfig

ROLES = ("planner", "judge", "reflector", "distiller", "summarizer")
# A reply that is (or whose function returns) a list of strings answers a request with n > 1: those
# texts become the result's `texts` (a plain string stays one text, whatever n asks for).
Reply = str | list[str] | Callable[[ChatRequest], "str | list[str]"] | Exception


def plan_json(*actions: tuple[int, str, str], language_plan: str = "plan") -> str:
    """A planner answer: (action_id, action_name, predicted_state) per action."""
    items = [{"action_id": i, "action_name": n, "predicted_state": p} for i, n, p in actions]
    return json.dumps({"language_plan": language_plan, "executable_plan": items})


def verdict_json(match: bool, reason: str = "") -> str:
    return json.dumps({"verdict": "match" if match else "mismatch", "reason": reason})


@dataclass
class _Spec:
    vision: bool = False


class ScriptedBackend:
    """Answers each request with the next scripted reply for its role (a string, a function of the
    request, or an exception to raise). A role with nothing left gets its default reply."""

    name = "scripted"

    def __init__(self, script: dict[str, list[Reply]] | None = None, *, model_id: str = "scripted/model",
                 vision: bool = False, defaults: dict[str, Reply] | None = None) -> None:
        self.model_id = model_id
        self.spec = _Spec(vision)
        self.script = {role: list(replies) for role, replies in (script or {}).items()}
        self.defaults: dict[str, Reply] = {
            "planner": plan_json(), "judge": verdict_json(True, "no contradiction"),
            "reflector": json.dumps({"rules": ["Default rule."]}),
            "distiller": json.dumps({"workflow": "Default workflow."}),
            "summarizer": json.dumps({"state_before": "before", "state_after": "after"}),
            **(defaults or {}),
        }
        self.requests: list[ChatRequest] = []

    def of(self, role: str) -> list[ChatRequest]:
        return [r for r in self.requests if r.role == role]

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        out = []
        for request in requests:
            self.requests.append(request)
            queue = self.script.get(request.role) or []
            reply = queue.pop(0) if queue else self.defaults[request.role]
            if isinstance(reply, Exception):
                raise reply
            text = reply(request) if callable(reply) else reply
            texts = list(text) if isinstance(text, list) else [text]
            prompt = sum(len(str(m["content"])) for m in request.messages) // 4
            out.append(ChatResult(texts, prompt, max(1, sum(len(t) for t in texts) // 4), 0.01, model=self.model_id))
        return out

    async def aclose(self) -> None:
        return None


class HashEmbedder(Embedder):
    """Deterministic 384-dim unit vectors from a hash of the text: equal texts have cosine 1, different
    texts are nearly orthogonal."""

    model_id = "test/hash-embedder"

    def _embed_uncached(self, texts: list[str]) -> np.ndarray:
        rows = []
        for text in texts:
            seed = int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big")
            vec = np.random.default_rng(seed).standard_normal(self.dim).astype(np.float32)
            rows.append(vec / np.linalg.norm(vec))
        return np.stack(rows)


APPLE_ACTIONS = [
    "find a Apple", "pick up the Apple", "find a Fridge", "open the Fridge",
    "put down the object in hand", "close the Fridge",
]
OK = "Last action executed successfully."


@dataclass
class AppleWorld:
    """Put the apple in the fridge. Progress 0.5 once the apple is held, 1.0 once it is in the fridge."""

    benchmark: str = "eb_alfred"
    max_steps: int = 30
    max_invalid: int | None = 10
    with_images: bool = False
    actions: list[str] = field(default_factory=lambda: list(APPLE_ACTIONS))
    step_calls: list[int] = field(default_factory=list)

    def reset(self, task: Task) -> Observation:
        self.at, self.holding, self.open, self.stored = "the start", False, False, False
        self.steps = self.invalid = 0
        return self._obs()

    def action_id(self, name: str) -> int:
        return self.actions.index(name)

    def close(self) -> None:
        return None

    def _obs(self) -> Observation:
        apple = "in the fridge" if self.stored else ("in your hand" if self.holding else "on the counter")
        text = (f"You are at {self.at}. Your hand is {'holding the Apple' if self.holding else 'empty'}. "
                f"The Fridge is {'open' if self.open else 'closed'}. The Apple is {apple}.")
        image = None
        if self.with_images:
            from PIL import Image

            image = Image.new("RGB", (4, 4), (self.steps * 20 % 255, 0, 0))
        return Observation(text, state={"at": self.at}, image=image)

    def _apply(self, action_id: int) -> str | None:
        name = self.actions[action_id]
        if name.startswith("find a "):
            self.at = name[len("find a "):]
            return None
        if name == "pick up the Apple":
            if self.holding:
                return "Robot is currently holding Apple"
            if self.at != "Apple" or self.stored:
                return "Cannot find Apple to pick up. Find the object before picking up it"
            self.holding = True
            return None
        if name in ("open the Fridge", "close the Fridge"):
            want_open = name.startswith("open")
            if self.at != "Fridge" or self.open == want_open:
                return "Open action failed." if want_open else "Close action failed"
            self.open = want_open
            return None
        if name == "put down the object in hand":
            if not self.holding:
                return "Robot is not holding any object"
            if self.at != "Fridge" or not self.open:
                return ("Putting the object on Fridge failed. First check the receptacle is open or not. "
                        "Also try other instances of the receptacle")
            self.holding, self.stored = False, True
            return None
        return "Unknown action"

    def step(self, action_id: int) -> StepResult:
        self.step_calls.append(action_id)
        self.steps += 1
        if not 0 <= action_id < len(self.actions):  # as EB-Navigation's env: an unknown id issues Done
            return StepResult("Last action Done executed successfully.", False, 0.0, False, True, self._obs(),
                              "env_done")
        error = self._apply(action_id)
        self.invalid += error is not None
        success = self.stored
        progress = 1.0 if self.stored else (0.5 if self.holding else 0.0)
        end = None
        if success:
            end = "success"
        elif self.steps >= self.max_steps:
            end = "max_steps"
        elif self.max_invalid is not None and self.invalid >= self.max_invalid:
            end = "max_invalid"
        feedback = OK if error is None else f"Last action is invalid. {error}"
        return StepResult(feedback, success, progress, error is not None, end is not None, self._obs(), end)


SOLVE = [
    (0, "find a Apple", "I am next to the Apple; my hand is empty."),
    (1, "pick up the Apple", "I am holding the Apple."),
    (2, "find a Fridge", "I am at the Fridge holding the Apple."),
    (3, "open the Fridge", "The Fridge is open."),
    (4, "put down the object in hand", "The Apple is in the Fridge; my hand is empty."),
]


@pytest.fixture
def task() -> Task:
    return Task(id="apple-1", benchmark="eb_alfred", subset="base", index=3,
                instruction="Put the apple in the fridge.", task_type="pick_and_place_simple")


@pytest.fixture
def embedder() -> HashEmbedder:
    return HashEmbedder()


def make_ctx(backend: ScriptedBackend, memory: Any = None, embedder: Any = None, *, seed: int = 7,
             **config: Any) -> EpisodeContext:
    return EpisodeContext(
        models={role: backend for role in ROLES},
        model_ids={"planner": "scripted/planner", "judge": "scripted/judge", "reflector": "scripted/judge",
                   "distiller": "scripted/planner", "summarizer": "scripted/judge"},
        memory=memory, embedder=embedder, run_id="run-test", seed=seed, config=WorldMindConfig(**config),
    )


def run_method(method: Any, task: Task, env: Any, ctx: EpisodeContext) -> Any:
    """One episode through the generic driver, then the runner's commit: the experience embedded and
    added to `ctx.memory` in order, each record item carrying `kept` (what the runner writes)."""
    import asyncio

    async def go() -> Any:
        outcome = await run_episode(method, task, env, ctx)
        items = []
        if ctx.memory is not None:
            for entry in await ctx.memory.embed(outcome.experience):
                kept = ctx.memory.add_embedded(entry)
                items.append({**entry.without_embeddings().model_dump(
                    mode="json", exclude={"key_embedding", "text_embedding"}), "kept": kept})
        outcome.record.experience = items
        return outcome.record

    return asyncio.run(go())


def run_wm(task: Task, env: Any, ctx: EpisodeContext) -> Any:
    """Full WorldMind with the context's config (its switches taken as given, for mechanism tests)."""
    method = WorldMind()
    method.config = ctx.config
    return run_method(method, task, env, ctx)


@pytest.fixture
def memory(embedder: HashEmbedder) -> WorldKnowledgeRepository:
    return WorldKnowledgeRepository(embedder)


@pytest.fixture
def kit() -> SimpleNamespace:
    """The helpers above, for test modules (conftest modules are not importable under importlib mode)."""
    return SimpleNamespace(
        APPLE_ACTIONS=APPLE_ACTIONS, AppleWorld=AppleWorld, ContextLengthError=ContextLengthError,
        HashEmbedder=HashEmbedder, OK=OK, ROLES=ROLES, SOLVE=SOLVE, ScriptedBackend=ScriptedBackend,
        make_ctx=make_ctx, plan_json=plan_json, verdict_json=verdict_json, run_method=run_method, run_wm=run_wm,
    )
