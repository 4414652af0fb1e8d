"""Synapse: trajectory-as-exemplar prompting with an exemplar memory (baselines.md §5).

- Prompt: ReAct's (§5(3)): the retrieved trajectories go into the examples slot of the system
  message, after the static EB examples, each headed "Retrieved successful trajectory i".
- Write (`finish`): when the success signal says success (`llm_judge` by default, C5: ReasoningBank's
  Synapse mode), one `exemplar` entry whose text is the episode in exemplar format: "Task: ...", then
  per planning call "Observation:" (what the planner was shown in text: the visual-state description it
  wrote, or the env's text stand-in, plus the env feedback that preceded the call) and "Output:" (its
  JSON cut to the actions that actually ran, ids stripped, §5(6)), then the feedback of each action
  that ran. Images are never stored. The entry's retrieval key is the specifier "benchmark / subset /
  instruction" (§5(4): the website/domain/task analogue; benchmark and subset are constant within a C4
  store, so the instruction drives the ranking).
- Read (`start`, once per episode: the key does not change): the current specifier's embedding,
  cosine against the stored keys (all-MiniLM-L6-v2, C7, instead of ada-002), same normalised instruction
  skipped (C4), top 3 (§5(4) `retrieve_top_k=3`), added best first while they fit the planner's context
  (context length minus the planner's output tokens minus the prompt without exemplars, 3 characters a
  token; a backend without a known context length takes all k). An empty memory gives plain ReAct
  (§5(6): no random exemplars).
- State abstraction needs no call (§5(5)): EB's feedback and the planner's own description abstract it.
- Calls: 1 per planning step; +1 memory judge per episode with `llm_judge` (0 with `env`).
"""

from __future__ import annotations

import json
from typing import Any, ClassVar

from pydantic import Field

from worldmind_local.agent.driver import Episode
from worldmind_local.agent.prompting import load_template, render
from worldmind_local.methods.base import MethodConfig, Proposal
from worldmind_local.methods.memory_common import (
    CHARS_PER_TOKEN,
    MemoryConfig,
    MemoryStats,
    StoreMethod,
    SuccessSignal,
    answer_field,
    context_length,
    decide_success,
    embed_query,
    finish_stats,
    new_entry,
    note_retrieved,
    planning_calls,
    remember_answer,
)
from worldmind_local.methods.react import ask_planner, eb_examples, react_messages

__all__ = ["Synapse", "SynapseConfig", "SynapseStats", "specifier", "render_exemplar"]

KIND = "exemplar"
DEFAULT_TOP_K = 3  # run_mind2web.py --retrieve_top_k 3
MAX_OBSERVATION_CHARS = 600


class SynapseConfig(MemoryConfig):
    success_signal: SuccessSignal = Field(
        "llm_judge", description="what decides a memory write: env success or an LLM judge of the trajectory")
    top_k: int | None = Field(None, ge=0, le=50, description="exemplars retrieved per episode (default 3)")


class SynapseStats(MemoryStats):
    exemplars_shown: int = 0
    exemplars_over_budget: int = 0


def specifier(benchmark: str, subset: str, instruction: str) -> str:
    """Synapse's task specifier (the retrieval key)."""
    return f"{benchmark} / {subset} / {instruction.strip()}"


def _observation(ep: Episode, index: int, answer: str, previous_feedback: str) -> str:
    seen = ep.state.get("observations", {}).get(index) or answer_field(answer, "visual_state_description")
    parts = [" ".join(seen.split())[:MAX_OBSERVATION_CHARS]] if seen else []
    parts.append(f"last feedback: {previous_feedback}" if previous_feedback else "start of the episode")
    return "; ".join(parts)


def _output(answer: str, ran: list[Any]) -> str:
    obj: dict[str, Any] = {}
    for name in ("reasoning_and_reflection", "language_plan"):
        value = answer_field(answer, name)
        if value:
            obj[name] = value
    obj["executable_plan"] = [{"action_name": s.action_name} for s in ran]
    return json.dumps(obj, ensure_ascii=False)


def render_exemplar(ep: Episode) -> str:
    """The episode as an exemplar: the task, then per planning call observation, output, feedback."""
    turns, previous = [f"Task: {ep.task.instruction.strip()}"], ""
    for index, answer, ran in planning_calls(ep):
        if not ran and not answer_field(answer, "language_plan"):
            continue   # an unusable output: nothing ran, nothing to demonstrate
        feedback = "\n".join(f"  {s.action_name} -> {s.feedback}" for s in ran) or "  (nothing ran)"
        turns.append(render(load_template("common", "synapse_turn"), observation=_observation(
            ep, index, answer, previous), output=_output(answer, ran), feedback=feedback))
        if ran:
            previous = ran[-1].feedback
    return "\n".join(turns)


class Synapse(StoreMethod):
    name: ClassVar[str] = "synapse"
    description: ClassVar[str] = ("Synapse: successful trajectories as exemplars, top-3 by task specifier, in "
                                  "ReAct's examples slot")
    config_class: ClassVar[type[MethodConfig]] = SynapseConfig
    config: SynapseConfig



    async def start(self, ep: Episode) -> None:
        stats = SynapseStats(success_signal=self.config.success_signal)
        static = eb_examples(ep, self.config.n_shots)
        stats.examples = static.count("## Example ")
        ep.state.update(stats=stats, examples=static, retrieved=[])
        k = self.config.top_k if self.config.top_k is not None else DEFAULT_TOP_K
        if ep.ctx.memory is None or k <= 0:
            return
        query = await embed_query(ep, specifier(ep.task.benchmark, ep.task.subset, ep.task.instruction))
        found = ep.ctx.memory.retrieve(query, k, kind=KIND, exclude_instruction=ep.task.instruction)
        shown = self._fit(ep, static, found)
        stats.exemplars_shown, stats.exemplars_over_budget = len(shown), len(found) - len(shown)
        note_retrieved(ep, shown, stats)
        ep.state["retrieved"] = [e.id for e in shown]
        if shown:
            blocks = [render(load_template("common", "synapse_exemplar"), number=i, exemplar=e.text.strip())
                      for i, e in enumerate(shown, 1)]
            block = render(load_template("common", "synapse_exemplars"), exemplars="\n\n".join(blocks))
            ep.state["examples"] = f"{static}\n\n{block}" if static else block

    async def plan(self, ep: Episode) -> Proposal:
        index = len(ep.record.plans)
        text, _ = ep.planner_view()
        if text is not None:
            ep.state.setdefault("observations", {})[index] = text
        messages = react_messages(ep, examples=ep.state["examples"], max_plan_actions=self.config.max_plan_actions)
        extra = {"retrieved": ep.state["retrieved"]} if ep.state["retrieved"] else {}
        proposal = await ask_planner(ep, messages, self.config, call_key=f"planner:{index}", extra=extra)
        remember_answer(ep, index, proposal.raw)
        return proposal

    async def finish(self, ep: Episode) -> None:
        stats: SynapseStats = ep.state["stats"]
        try:
            if ep.ctx.memory is None:
                return
            success, _ = await decide_success(ep, self.config, stats)
            if success and ep.trajectory:
                key = specifier(ep.task.benchmark, ep.task.subset, ep.task.instruction)
                ep.experience.append(new_entry(ep, KIND, render_exemplar(ep), success=True,
                                               signal=self.config.success_signal, key=key))
        finally:
            finish_stats(ep, stats)

    def _fit(self, ep: Episode, static: str, found: list[Any]) -> list[Any]:
        """The retrieved exemplars, best first, while they fit the planner's context (§5(5))."""
        limit = context_length(ep.calls.backend("planner"))
        if limit is None:
            return list(found)
        base = sum(len(str(m["content"])) for m in react_messages(
            ep, examples=static, max_plan_actions=self.config.max_plan_actions)) // CHARS_PER_TOKEN
        room = limit - self.config.planner_max_tokens - base
        shown = []
        for entry in found:
            cost = (len(entry.text) + 60) // CHARS_PER_TOKEN
            if cost > room:
                break
            shown.append(entry)
            room -= cost
        return shown
