"""What the memory baselines (NaiveMem, Synapse, AWM, ReasoningBank) share: baselines.md §1 C4-C8.

- The success signal for memory writes (C5): `env` (the episode's own success, as WorldMind and NaiveMem
  use it) or `llm_judge` (one call per episode to the backbone, ReasoningBank's and AWM's autoeval).
  The judge sees the instruction, the C6 trajectory, the planner's last reasoning and its last
  visual-state description: never the env's success, progress or why the episode ended. Which signal
  decided and its value go into the episode's `method_stats` (`MemoryStats`).
- The canonical trajectory rendering (C6): per planning call a think block (the call's
  `reasoning_and_reflection` + `language_plan`), then one line per action that ran, by name, with the
  env's feedback.
- The backbone roles. The baselines' memory-construction calls (judge, extraction, induction) are made
  by the backbone itself (baselines.md §6(5), §7(5): the self-improvement setting), not by the
  `--judge` model that WorldMind's verifier uses. They run under their own role names
  (`memory_judge`, `extractor`, `inductor`) so their tokens are booked apart; a role without its own
  backend uses the planner's. Seeds come from the call keys, so every construction call repeats.
- Building entries (`StoredExperience`) with provenance, and the query embedding.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pydantic import BaseModel, Field

from worldmind_local.agent.calls import ModelCalls
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render
from worldmind_local.methods.base import BaseMethod, MethodConfig
from worldmind_local.records import StepRecord

if TYPE_CHECKING:
    from worldmind_local.agent.driver import Episode
    from worldmind_local.memory.store import ExperienceStore, StoredExperience

__all__ = [
    "SuccessSignal",
    "BACKBONE_ROLES",
    "MemoryConfig",
    "MemoryStats",
    "Verdict",
    "JUDGE_SCHEMA",
    "backbone_calls",
    "context_length",
    "CHARS_PER_TOKEN",
    "remember_answer",
    "answer_field",
    "planning_calls",
    "render_trajectory",
    "last_reasoning",
    "judge_episode",
    "parse_verdict",
    "decide_success",
    "new_entry",
    "embed_query",
    "make_store",
    "load_store",
    "finish_stats",
    "note_retrieved",
    "think_of",
    "action_line",
    "backbone_model_id",
]

SuccessSignal = Literal["env", "llm_judge"]
BACKBONE_ROLES = ("memory_judge", "extractor", "inductor")
JUDGE_TEMPERATURE = 0.0        # ReasoningBank autoeval (baselines.md §7(4))
MAX_THOUGHTS_CHARS = 1500
CHARS_PER_TOKEN = 3            # a conservative estimate when fitting text into a context

JUDGE_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "thoughts": {"type": "string", "maxLength": MAX_THOUGHTS_CHARS},
        "status": {"type": "string", "enum": ["success", "failure"]},
    },
    "required": ["thoughts", "status"],
    "additionalProperties": False,
}


class MemoryConfig(MethodConfig):
    """Settings every memory baseline has (the subclasses set their own `success_signal` default)."""

    success_signal: SuccessSignal = Field(
        "llm_judge", description="what decides a memory write: env success or an LLM judge of the trajectory")
    budget_unit: Literal["episodes", "entries"] = Field(
        "episodes", description="unit of --memory-budget: source episodes (paper) or entries")
    memory_judge_max_tokens: int = Field(512, ge=16, le=8192, description="token budget of the memory judge")


class MemoryStats(BaseModel):
    """Per-episode counters of a memory baseline (`EpisodeRecord.method_stats`)."""

    success_signal: str = "env"
    signal_success: bool | None = None   # the signal's value for this episode (None: no memory, no write)
    judge_calls: int = 0
    judge_unparseable: int = 0
    judge_thoughts: str = ""
    retrieved: int = 0
    stored: int = 0
    examples: int = 0


@dataclass(frozen=True, slots=True)
class Verdict:
    success: bool
    thoughts: str
    unparseable: bool = False


# -- calls ------------------------------------------------------------------------------------------

def backbone_calls(ep: Episode) -> ModelCalls:
    """The episode's calls: the memory-construction roles (memory_judge, extractor, inductor) are served
    by the backbone (the planner's backend) through `calls.ROLE_FALLBACK` unless the run maps them."""
    return ep.calls


def context_length(backend: Any) -> int | None:
    """A backend's context length in tokens, from its spec (looking through wrappers); None if unknown."""
    for _ in range(8):
        if backend is None:
            return None
        value = getattr(getattr(backend, "spec", None), "context_length", None)
        if isinstance(value, int) and value > 0:
            return value
        backend = getattr(backend, "inner", None)
    return None


def backbone_model_id(ep: Episode) -> str:
    return ep.ctx.model_ids.get("planner", "")


# -- the trajectory (C6) ------------------------------------------------------------------------------

def remember_answer(ep: Episode, index: int, text: str) -> None:
    """Keep planning call `index`'s raw answer: the think blocks of C6 and Synapse's outputs need it."""
    ep.state.setdefault("answers", {})[index] = text


def answer_field(text: str, name: str) -> str:
    """One string field of a planner answer ("" when absent or unparseable)."""
    try:
        value = extract_first_json_object(text).get(name)
    except PlanParseError:
        return ""
    return value.strip() if isinstance(value, str) else ""


def think_of(text: str) -> str:
    parts = [answer_field(text, "reasoning_and_reflection"), answer_field(text, "language_plan")]
    return " ".join(p for p in parts if p)


def planning_calls(ep: Episode) -> list[tuple[int, str, list[StepRecord]]]:
    """(call index, raw answer, the env steps it ran) per planning call, in order."""
    answers: dict[int, str] = ep.state.get("answers", {})
    steps: dict[int, list[StepRecord]] = {}
    for step in ep.trajectory:
        if step.env_step:
            steps.setdefault(step.plan_index, []).append(step)
    return [(i, answers.get(i, ""), steps.get(i, [])) for i in range(len(ep.record.plans))]


def action_line(step: StepRecord) -> str:
    note = " (a random action stood in for an unusable output)" if step.substituted else ""
    return f"{step.action_name}{note} -> {step.feedback}"


def render_trajectory(ep: Episode) -> str:
    """C6: per planning call a think block, then each action that ran (by name) with its feedback."""
    blocks = []
    for n, (_, answer, steps) in enumerate(planning_calls(ep), 1):
        think = think_of(answer) or "(no usable output)"
        lines = [f"Planning call {n}", f"Think: {think}"]
        lines += [f"  {action_line(s)}" for s in steps]
        blocks.append("\n".join(lines))
    return "\n".join(blocks) if blocks else "(no planning calls)"


def last_reasoning(ep: Episode) -> tuple[str, str]:
    """(the planner's last reasoning, its last visual-state description) from the latest usable answer."""
    for _, answer, _ in reversed(planning_calls(ep)):
        think = think_of(answer)
        if think:
            return think, answer_field(answer, "visual_state_description")
    return "", ""


# -- the success signal (C5) --------------------------------------------------------------------------

_STATUS = re.compile(r"status\W*(success|failure)", re.IGNORECASE)


def parse_verdict(text: str) -> Verdict:
    """The judge's JSON, or ReasoningBank's two-line "Thoughts: ... / Status: ..." form; anything else
    is a failure (the reference's "failure when in doubt") marked unparseable."""
    try:
        obj = extract_first_json_object(text)
        status = str(obj.get("status", "")).strip().lower()
        thoughts = str(obj.get("thoughts", "")).strip()
        if status in ("success", "failure"):
            return Verdict(status == "success", thoughts[:MAX_THOUGHTS_CHARS])
    except PlanParseError:
        pass
    found = _STATUS.findall(text)
    if found:
        thoughts = text.split("Status", 1)[0].replace("Thoughts:", "").strip()
        return Verdict(found[-1].lower() == "success", thoughts[:MAX_THOUGHTS_CHARS])
    return Verdict(False, "", unparseable=True)


async def judge_episode(ep: Episode, *, max_tokens: int, call_key: str = "memory_judge") -> Verdict:
    """One backbone call: did the trajectory achieve the instruction? (T=0, ReasoningBank's autoeval)."""
    reasoning, visual = last_reasoning(ep)
    visual_section = f"\n## Your last description of what you saw\n{visual}\n" if visual else ""
    user = render(load_template("common", "memory_judge_user"), instruction=ep.task.instruction.strip(),
                  trajectory=render_trajectory(ep), reasoning=reasoning or "(none)", visual=visual_section)
    messages = [{"role": "system", "content": load_template("common", "memory_judge_system").strip()},
                {"role": "user", "content": user}]
    calls = backbone_calls(ep)
    request = calls.request("memory_judge", messages, call_key=call_key, max_tokens=max_tokens,
                            json_schema=JUDGE_SCHEMA, temperature=JUDGE_TEMPERATURE)
    result = await calls.ask(request, call_key=call_key)
    return parse_verdict(result.text)


async def decide_success(ep: Episode, config: MemoryConfig, stats: MemoryStats) -> tuple[bool, str]:
    """(success under the configured signal, the judge's thoughts or "") and the stats updated."""
    stats.success_signal = config.success_signal
    if config.success_signal == "env":
        stats.signal_success = bool(ep.record.success)
        return stats.signal_success, ""
    verdict = await judge_episode(ep, max_tokens=config.memory_judge_max_tokens)
    stats.judge_calls += 1
    stats.judge_unparseable += int(verdict.unparseable)
    stats.judge_thoughts = verdict.thoughts
    stats.signal_success = verdict.success
    return verdict.success, verdict.thoughts


# -- entries and retrieval ----------------------------------------------------------------------------

def new_entry(ep: Episode, kind: str, text: str, *, success: bool | None, signal: str, key: str = "",
              title: str | None = None, description: str | None = None) -> StoredExperience:
    """An entry with the episode's provenance (the runner embeds and commits it)."""
    from worldmind_local.memory.store import StoredExperience

    task = ep.task
    judge_model = backbone_model_id(ep) if signal == "llm_judge" else ""
    return StoredExperience(
        kind=kind, text=text, instruction=task.instruction, key=key, benchmark=task.benchmark,
        subset=task.subset, episode=task.index, task_id=task.id, success=success, success_signal=signal,
        title=title, description=description, planner_model=ep.ctx.model_ids.get("planner", ""),
        judge_model=judge_model, run_id=ep.ctx.run_id,
    )


async def embed_query(ep: Episode, text: str) -> Any:
    """The embedding of a retrieval query (the instruction, or Synapse's specifier)."""
    memory = ep.ctx.memory
    embedder = ep.ctx.embedder or getattr(memory, "embedder", None)
    if embedder is None:
        raise ValueError("EpisodeContext has a memory but no embedder to embed the retrieval query")
    return (await embedder.aencode([text]))[0]


def note_retrieved(ep: Episode, entries: Sequence[Any], stats: MemoryStats) -> list[str]:
    """Book retrieved entries on the record (ids, in first-retrieval order); returns their ids."""
    ids = [e.id for e in entries]
    for entry_id in ids:
        if entry_id not in ep.record.retrieved_ids:
            ep.record.retrieved_ids.append(entry_id)
    stats.retrieved = len(ep.record.retrieved_ids)
    return ids


class StoreMethod(BaseMethod):
    """A baseline whose global memory is an `ExperienceStore` (NaiveMem, Synapse, AWM, ReasoningBank)."""

    memory_scope: ClassVar[Any] = "global"
    config: MemoryConfig

    def new_memory(self, embedder: Any, budget: int | None) -> Any | None:
        return make_store(embedder, budget, self.config)

    def load_memory(self, path: str, embedder: Any, budget: int | None) -> Any | None:
        return load_store(path, embedder, budget, self.config)


def make_store(embedder: Any, budget: int | None, config: MemoryConfig, *, dedup: str = "none") -> ExperienceStore:
    from worldmind_local.memory.store import ExperienceStore

    return ExperienceStore(embedder, budget=budget, budget_unit=config.budget_unit, dedup=dedup)


def load_store(path: str, embedder: Any, budget: int | None, config: MemoryConfig, *,
               dedup: str = "none") -> ExperienceStore:
    """A seed store (--memory-from): its rows, under this run's budget; its own commit log dropped."""
    from worldmind_local.memory.store import ExperienceStore

    store = ExperienceStore.load(path, embedder, budget=budget, budget_unit=config.budget_unit, dedup=dedup)
    store.commits = []
    return store


def finish_stats(ep: Episode, stats: MemoryStats) -> None:
    stats.stored = len(ep.experience)
    ep.record.method_stats = stats.model_dump(mode="json")
