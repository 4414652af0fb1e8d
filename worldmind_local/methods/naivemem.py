"""NaiveMem: WorldMind's controlled-memory control (baselines.md §8): "is it just the memory?".

Raw successful trajectories, no distillation, no verification, retrieved by WorldMind's own retriever.

- Prompt: WorldMind's planner prompt (its system prompt, guidelines, worked examples with predicted
  states and output schema with a per-action `predicted_state`, produced but never checked): the paper's
  "Baseline" row (`worldmind_baseline`) plus this memory. §8(2): "Prompt skeleton = WorldMind's".
- Write (`finish`, no LLM call): when the success signal says success (`env` by default, C5: WorldMind's
  own `task_success`), one `trajectory` entry. Its text is, by default, exactly what WorldMind's
  Goal-Experience distiller receives (`annotate_trajectory`: step, action id and name, feedback,
  task_progress with its increases marked), §8(2)/(6): that isolates distillation as the only
  difference. [decision] This keeps the *past* episodes' ground-truth progress in the stored text as §8
  says, although the brief asked for the C6 rendering: `trajectory_format="c6"` stores the C6 rendering
  instead (progress-free; §8(6)'s logged ablation). Exact-text duplicates are refused by the store
  (§8(2)); the optional 0.95 cosine filter is not applied.
- Read (`plan`, every planner call, as WorldMind): skip entries with the same normalised instruction,
  score the rest by all-MiniLM-L6-v2 cosine between instructions, top k = WorldMind's own k for the
  benchmark (`default_top_k`: 2 on EB-ALFRED and EB-Navigation, 1 on EB-Habitat as in the official
  configs; §8(4) names eb-alf.yaml's 2); the block goes where
  WorldMind's Goal Experience goes: in the user message after the instruction, before the action
  history, under "Knowledge from your World Knowledge Repository" (`planner_messages(experience=...)`).
- Calls: 1 per planning step; 0 per episode with `success_signal="env"` (+1 memory judge with
  `llm_judge`).
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal

from pydantic import BaseModel, Field

from worldmind_local.agent.distiller import annotate_trajectory
from worldmind_local.agent.driver import Episode
from worldmind_local.agent.plan import PlanParseError, parse_plan, planner_schema
from worldmind_local.agent.prompting import format_examples, load_template, planner_messages, render
from worldmind_local.methods.base import MethodConfig, Proposal
from worldmind_local.methods.memory_common import (
    MemoryConfig,
    MemoryStats,
    StoreMethod,
    SuccessSignal,
    decide_success,
    embed_query,
    finish_stats,
    load_store,
    make_store,
    new_entry,
    note_retrieved,
    remember_answer,
    render_trajectory,
)

__all__ = ["NaiveMem", "NaiveMemConfig", "NaiveMemStats", "format_trajectories"]

KIND = "trajectory"
DEFAULT_TOP_K = 2  # WorldMind's k where a benchmark adapter sets none


class NaiveMemConfig(MemoryConfig):
    success_signal: SuccessSignal = Field(
        "env", description="what decides a memory write: env success or an LLM judge of the trajectory")
    top_k: int | None = Field(None, ge=0, le=50, description="trajectories retrieved per planner call "
                                                           "(default: WorldMind's k for the benchmark)")
    trajectory_format: Literal["distiller_input", "c6"] = Field(
        "distiller_input", description="NaiveMem's stored text: WorldMind's distiller input (with past progress) "
                                       "or the C6 rendering")


class NaiveMemStats(MemoryStats):
    trajectory_format: str = "distiller_input"


def format_trajectories(entries: list[Any]) -> str:
    """The retrieved trajectories under their header ("" when none)."""
    if not entries:
        return ""
    blocks = [render(load_template("common", "naivemem_trajectory"), number=i, instruction=e.instruction.strip(),
                     steps=e.text.strip()) for i, e in enumerate(entries, 1)]
    return render(load_template("common", "naivemem_block"), trajectories="\n\n".join(blocks))


class NaiveMem(StoreMethod):
    name: ClassVar[str] = "naivemem"
    description: ClassVar[str] = ("NaiveMem: raw successful trajectories, top-2 by instruction, in WorldMind's "
                                  "prompt; no distillation, no verification")
    config_class: ClassVar[type[MethodConfig]] = NaiveMemConfig
    config: NaiveMemConfig

    def new_memory(self, embedder: Any, budget: int | None) -> Any | None:
        return make_store(embedder, budget, self.config, dedup="text")

    def load_memory(self, path: str, embedder: Any, budget: int | None) -> Any | None:
        return load_store(path, embedder, budget, self.config, dedup="text")

    async def start(self, ep: Episode) -> None:
        cfg = self.config
        stats = NaiveMemStats(success_signal=cfg.success_signal, trajectory_format=cfg.trajectory_format)
        ep.state.update(stats=stats, examples=self._examples(ep, stats), query=None)
        ep.state["top_k"] = cfg.top_k if cfg.top_k is not None else getattr(ep.adapter, "default_top_k", DEFAULT_TOP_K)
        if ep.ctx.memory is not None and ep.state["top_k"] > 0:
            ep.state["query"] = await embed_query(ep, ep.task.instruction)

    async def plan(self, ep: Episode) -> Proposal:
        cfg, index = self.config, len(ep.record.plans)
        retrieved = self._retrieve(ep)
        text, image = ep.planner_view()
        messages = planner_messages(
            ep.env.benchmark, actions=ep.actions, instruction=ep.task.instruction, history=ep.trajectory,
            observation=text, image=image, experience=format_trajectories(retrieved),
            examples=ep.state["examples"], max_plan_actions=cfg.max_plan_actions,
        )
        key = f"planner:{index}"
        request = ep.calls.request("planner", messages, call_key=key, max_tokens=cfg.planner_max_tokens,
                                   json_schema=planner_schema(len(ep.actions), cfg.max_plan_actions))
        result = await ep.calls.ask(request, call_key=key)
        remember_answer(ep, index, result.text)
        extra = {"retrieved": note_retrieved(ep, retrieved, ep.state["stats"])} if ep.state["query"] is not None else {}
        try:
            return Proposal(parse_plan(result.text), result, result.text, extra=extra)
        except PlanParseError as exc:
            return Proposal(None, result, result.text, error=str(exc), extra=extra)

    async def finish(self, ep: Episode) -> None:
        stats: NaiveMemStats = ep.state["stats"]
        try:
            if ep.ctx.memory is None:
                return
            success, _ = await decide_success(ep, self.config, stats)
            if success and ep.trajectory:
                text = (annotate_trajectory(ep.trajectory) if self.config.trajectory_format == "distiller_input"
                        else render_trajectory(ep))
                ep.experience.append(new_entry(ep, KIND, text, success=True, signal=self.config.success_signal))
        finally:
            finish_stats(ep, stats)

    # -- parts ---------------------------------------------------------------------------------------

    def _examples(self, ep: Episode, stats: BaseModel) -> str:
        """WorldMind's worked examples (with predicted states), never from the evaluated task."""
        n = self.config.n_shots if self.config.n_shots is not None else getattr(ep.adapter, "default_n_shots", 0)
        make = getattr(ep.adapter, "worked_examples", None)
        if not n or make is None:
            return ""
        examples = make(n, data_dir=ep.ctx.data_dir, exclude=(ep.task.id, ep.task.instruction))
        stats.examples = len(examples)  # type: ignore[attr-defined]
        return format_examples(examples, with_predictions=True)

    def _retrieve(self, ep: Episode) -> list[Any]:
        query = ep.state["query"]
        if query is None or ep.ctx.memory is None:
            return []
        return ep.ctx.memory.retrieve(query, ep.state["top_k"], kind=KIND, exclude_instruction=ep.task.instruction)
