"""AWM: Agent Workflow Memory, online (baselines.md §6), on ReAct's planner.

- Prompt: ReAct's; the current workflow text is injected whole (no retrieval), after the system block
  and examples, before the instruction line, under "Workflows induced from past successful tasks"
  (`react_messages(extra_system=...)`), with a one-line reminder that ids come from the current list
  instead of the reference's web-syntax footer (§6(5)). Before the first success the run is ReAct.
- Write (`finish`): the success signal (`llm_judge` by default, C5: `--criteria autoeval`) decides.
  On success: one `trajectory` entry (the C6 rendering), then one induction call (the `inductor` role,
  the backbone) over ALL successes so far, the committed ones plus this one: grouped by normalised
  instruction (the template id is not exposed to agents, §6(5)), one trajectory sampled per group
  (`num_samples=1`, seeded from the run seed, task and call key), rendered "Query ... Actions: <C6>",
  after the embodied one-shot (`prompts/common/awm_one_shot_<benchmark>.md`, written from EB's static
  examples, never from test episodes). Its output becomes one `workflow` entry; the newest one is the
  workflow text (overwrite semantics: older ones stay in the dataset as history only).
- [decision, §6(5)] Re-induce only when the success set changed, i.e. after a judged success: the
  reference re-induces after every task; with an unchanged success set it would only re-sample.
- [decision] The induction prompt must fit: the oldest groups are dropped first (§6(6)) until the
  examples fit the inductor's context (context minus its output tokens minus the rest of the prompt,
  3 characters a token) and `induction_max_chars`; the number dropped is logged in the stats.
- [decision] C4's self-exclusion cannot apply to one text induced from many tasks: the workflow is
  injected whole even when a past task had the same instruction.
- Defaults: induction T=1.0 and 2048 output tokens (§6(4), `induce_prompt.py`); the judge T=0.
- Calls: 1 per planning step; per episode +1 memory judge (`llm_judge`) and +1 induction when the
  episode counts as a success.
"""

from __future__ import annotations

import random
import re
from typing import Any, ClassVar

from pydantic import Field

from worldmind_local.agent.calls import derive_seed
from worldmind_local.agent.driver import Episode
from worldmind_local.agent.prompting import TemplateError, load_template, render
from worldmind_local.memory.store import normalize_instruction
from worldmind_local.methods.base import MethodConfig, Proposal
from worldmind_local.methods.memory_common import (
    CHARS_PER_TOKEN,
    MemoryConfig,
    MemoryStats,
    StoreMethod,
    SuccessSignal,
    backbone_calls,
    context_length,
    decide_success,
    finish_stats,
    new_entry,
    note_retrieved,
    remember_answer,
    render_trajectory,
)
from worldmind_local.methods.react import ask_planner, eb_examples, react_messages

__all__ = ["AgentWorkflowMemory", "AWMConfig", "AWMStats"]

TRAJECTORY, WORKFLOW = "trajectory", "workflow"
_FENCE = re.compile(r"^```[a-zA-Z]*\n|\n?```$")


class AWMConfig(MemoryConfig):
    success_signal: SuccessSignal = Field(
        "llm_judge", description="what decides a memory write: env success or an LLM judge of the trajectory")
    induction_temperature: float = Field(1.0, ge=0.0, le=2.0, description="AWM induction temperature (reference 1.0)")
    induction_max_tokens: int = Field(2048, ge=16, le=32768, description="AWM induction output tokens (reference 2048)")
    induction_max_chars: int = Field(24000, ge=500, description="cap on the induction examples' characters "
                                                                "(oldest instruction groups dropped first)")


class AWMStats(MemoryStats):
    workflow_id: str = ""           # the workflow text this episode was shown ("" before the first one)
    inductions: int = 0
    induction_groups: int = 0       # instruction groups the induction saw
    induction_groups_dropped: int = 0
    induction_empty: int = 0


class AgentWorkflowMemory(StoreMethod):
    name: ClassVar[str] = "awm"
    description: ClassVar[str] = ("AWM (online): one workflow text re-induced from all judged successes, "
                                  "injected whole into ReAct's prompt")
    config_class: ClassVar[type[MethodConfig]] = AWMConfig
    config: AWMConfig



    async def start(self, ep: Episode) -> None:
        stats = AWMStats(success_signal=self.config.success_signal)
        examples = eb_examples(ep, self.config.n_shots)
        stats.examples = examples.count("## Example ")
        workflow = ep.ctx.memory.latest(WORKFLOW) if ep.ctx.memory is not None else None
        block = ""
        if workflow is not None:
            block = render(load_template("common", "awm_block"), workflows=workflow.text.strip())
            stats.workflow_id = workflow.id
            note_retrieved(ep, [workflow], stats)
        ep.state.update(stats=stats, examples=examples, block=block)

    async def plan(self, ep: Episode) -> Proposal:
        index = len(ep.record.plans)
        messages = react_messages(ep, examples=ep.state["examples"], extra_system=ep.state["block"],
                                  max_plan_actions=self.config.max_plan_actions)
        stats: AWMStats = ep.state["stats"]
        extra = {"workflow": stats.workflow_id} if stats.workflow_id else {}
        proposal = await ask_planner(ep, messages, self.config, call_key=f"planner:{index}", extra=extra)
        remember_answer(ep, index, proposal.raw)
        return proposal

    async def finish(self, ep: Episode) -> None:
        stats: AWMStats = ep.state["stats"]
        try:
            if ep.ctx.memory is None:
                return
            success, _ = await decide_success(ep, self.config, stats)
            if not success:
                return
            current = new_entry(ep, TRAJECTORY, render_trajectory(ep), success=True,
                                signal=self.config.success_signal)
            ep.experience.append(current)
            workflow = await self._induce(ep, [*self._successes(ep), current], stats)
            if workflow:
                ep.experience.append(new_entry(ep, WORKFLOW, workflow, success=None,
                                               signal=self.config.success_signal))
        finally:
            finish_stats(ep, stats)

    # -- induction -------------------------------------------------------------------------------------

    @staticmethod
    def _successes(ep: Episode) -> list[Any]:
        return [e for e in ep.ctx.memory.entries(TRAJECTORY) if e.success]

    def _sample(self, ep: Episode, successes: list[Any]) -> list[Any]:
        """One trajectory per instruction group (oldest group first), sampled with a seeded RNG."""
        groups: dict[str, list[Any]] = {}
        for entry in successes:
            groups.setdefault(normalize_instruction(entry.instruction), []).append(entry)
        rng = random.Random(derive_seed(ep.ctx.seed, ep.task.index, "inductor:sample"))
        return [rng.choice(group) for group in groups.values()]

    def _fit(self, ep: Episode, blocks: list[str], fixed_chars: int, stats: AWMStats) -> list[str]:
        """Drop the oldest groups until the examples fit (always keeping the newest)."""
        room = self.config.induction_max_chars
        limit = context_length(backbone_calls(ep).backend("inductor"))
        if limit is not None:
            room = min(room, (limit - self.config.induction_max_tokens) * CHARS_PER_TOKEN - fixed_chars)
        while len(blocks) > 1 and sum(len(b) + 2 for b in blocks) > room:
            blocks = blocks[1:]
            stats.induction_groups_dropped += 1
        return blocks

    async def _induce(self, ep: Episode, successes: list[Any], stats: AWMStats) -> str:
        cfg = self.config
        system = load_template("common", "awm_induction_system").strip()
        try:
            one_shot = load_template("common", f"awm_one_shot_{ep.task.benchmark}").strip()
        except TemplateError:
            one_shot = load_template("common", "awm_one_shot_eb_alfred").strip()
        blocks = [render(load_template("common", "awm_example"), instruction=e.instruction.strip(),
                         trajectory=e.text.strip()) for e in self._sample(ep, successes)]
        blocks = self._fit(ep, blocks, len(system) + len(one_shot) + 200, stats)
        stats.induction_groups = len(blocks)
        user = render(load_template("common", "awm_induction_user"), one_shot=one_shot, examples="\n\n".join(blocks))
        calls = backbone_calls(ep)
        request = calls.request("inductor", [{"role": "system", "content": system}, {"role": "user", "content": user}],
                                call_key="inductor", max_tokens=cfg.induction_max_tokens,
                                temperature=cfg.induction_temperature)
        result = await calls.ask(request, call_key="inductor")
        stats.inductions += 1
        text = _FENCE.sub("", result.text.strip()).strip()
        stats.induction_empty += int(not text)
        return text
