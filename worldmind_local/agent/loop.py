"""The WorldMind episode loop (paper Sec. 2, Alg. 1): plan, act, verify, reflect, distill.

Per planner call: retrieve Goal and Process Experience for the task instruction (embedded once per
episode), ask the planner for a plan with a predicted state per action, then execute the plan in order
until the first invalid action, the end of the plan, or the end of the episode, and re-plan with the
history. Verification (abstract the actual state, judge it against the prediction) runs on the first
executed action of each plan, or on every executed action, and never on a skipped prediction. A
judged mismatch asks the reflector for corrective rules, which enter the repository as Process
Experience before the next planner call; a success is distilled into Goal Experience.

The verifications of one plan run concurrently once the plan has executed (the plan cannot change
in between), so a batching backend sees them together; their experience is added in step order.
Unusable planner outputs follow EmbodiedBench per benchmark (see `agent.plan`).
"""

from __future__ import annotations

import asyncio
import random
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from models.base import ChatResult, ContextLengthError
from worldmind_local.agent.abstractor import StateAbstractor, observation_image
from worldmind_local.agent.calls import ModelCalls, backend_for, derive_seed, has_vision
from worldmind_local.agent.distiller import GoalDistiller
from worldmind_local.agent.judge import Judge
from worldmind_local.agent.plan import (
    POLICY_RANDOM,
    PlannedAction,
    PlanParseError,
    parse_plan,
    planner_schema,
    screen_ids,
    unusable_output_policy,
)
from worldmind_local.agent.prompting import format_history, planner_messages
from worldmind_local.agent.reflector import Reflector
from worldmind_local.env import Env, Observation, Task
from worldmind_local.records import EpisodeRecord, PlanRecord, StepRecord, TokenCount, taxonomy_label

if TYPE_CHECKING:  # methods.base imports nothing from here; keep the import one-way at run time
    from worldmind_local.methods.base import EpisodeContext

__all__ = ["EpisodeLoop", "DEFAULT_TOP_K", "INVALID_OUTPUT_NAME"]

DEFAULT_TOP_K = 2                       # the paper's k when neither the config nor the runner sets one
INVALID_OUTPUT_NAME = "invalid action"  # EB's episode-log description of an unusable planner output


@dataclass(slots=True)
class _Check:
    """One executed action awaiting verification."""

    step: StepRecord
    before: Observation
    after: Observation
    history: list[StepRecord]


class EpisodeLoop:
    def __init__(self, task: Task, env: Env, ctx: EpisodeContext, *, method: str = "worldmind") -> None:
        self.task, self.env, self.ctx, self.cfg = task, env, ctx, ctx.config
        self.record = EpisodeRecord(
            task_id=task.id, benchmark=task.benchmark, subset=task.subset, index=task.index,
            instruction=task.instruction, task_type=task.task_type, method=method, run_id=ctx.run_id,
            seed=ctx.seed, model_ids=dict(ctx.model_ids), config=self.cfg.to_dict(),
        )
        self.calls = ModelCalls(ctx.models, self.record, seed=ctx.seed, task_index=task.index,
                                temperature=self.cfg.temperature)
        bench = env.benchmark
        self.policy = unusable_output_policy(bench)
        self.abstractor = StateAbstractor(bench, self.calls, mode=self.cfg.abstract_with,
                                          max_tokens=self.cfg.summarizer_max_tokens)
        self.judge = Judge(bench, self.calls, max_tokens=self.cfg.judge_max_tokens)
        self.reflector = Reflector(bench, self.calls, max_tokens=self.cfg.reflector_max_tokens,
                                   max_rules=self.cfg.max_rules)
        self.distiller = GoalDistiller(bench, self.calls, max_tokens=self.cfg.distiller_max_tokens)
        self.top_k = DEFAULT_TOP_K if self.cfg.top_k is None else self.cfg.top_k
        images = self.cfg.planner_images
        self.planner_images = bool(has_vision(backend_for(ctx.models, "planner"))) if images is None else images
        summarizer = backend_for(ctx.models, "summarizer")
        if self.cfg.abstract_with == "vlm" and has_vision(summarizer) is False:
            raise ValueError(f"abstract_with='vlm' needs a vision-language summarizer; "
                             f"{summarizer.model_id} is a text-only model")
        self.query: Any = None
        self.invalid = 0
        self.done = False

    # -- the episode --------------------------------------------------------------------------------

    async def run(self) -> EpisodeRecord:
        t0 = time.perf_counter()
        self.obs = self._before = self.env.reset(self.task)
        self.actions = list(self.env.actions)
        rec = self.record
        try:
            self.query = await self._embed_query()
            planner_limit = self.env.max_steps + (self.env.max_invalid or self.env.max_steps) + 1
            while not self.done:
                if rec.planner_calls >= planner_limit:
                    self._end("planner_limit")
                    break
                await self._plan_and_act()
            if rec.success and self.cfg.goal_experience and self.ctx.memory is not None:
                await self._distill()
        except ContextLengthError as exc:  # deterministic: the episode outgrew the model's context
            rec.error = str(exc)
            if not rec.success:  # a success stays a success even if its distillation did not fit
                rec.end_reason = "context_length"
        rec.taxonomy = taxonomy_label(rec.success, rec.end_reason)
        rec.wall_seconds = round(time.perf_counter() - t0, 6)
        return rec

    def _end(self, reason: str) -> None:
        self.done = True
        self.record.end_reason = reason

    async def _embed_query(self) -> Any:
        memory = self.ctx.memory
        wanted = self.cfg.goal_experience or self.cfg.process_experience
        if memory is None or not wanted or self.top_k == 0:
            return None
        embedder = self.ctx.embedder or getattr(memory, "embedder", None)
        if embedder is None:
            raise ValueError("EpisodeContext has a memory but no embedder to embed the task instruction")
        return (await embedder.aencode([self.task.instruction]))[0]

    def _retrieve(self) -> tuple[list[Any], list[Any], float | None]:
        memory, k = self.ctx.memory, self.top_k
        if memory is None or self.query is None:
            return [], [], None
        t0 = time.perf_counter()
        process = memory.retrieve(self.query, "process", k) if self.cfg.process_experience else []
        goal = (memory.retrieve(self.query, "goal", k, exclude_instruction=self.task.instruction)
                if self.cfg.goal_experience else [])
        return goal, process, time.perf_counter() - t0

    # -- planning -----------------------------------------------------------------------------------

    async def _plan_and_act(self) -> None:
        rec, index = self.record, len(self.record.plans)
        goal, process, seconds = self._retrieve()
        image = observation_image(self.obs) if self.planner_images else None
        messages = planner_messages(
            self.env.benchmark, actions=self.actions, instruction=self.task.instruction,
            observation=self.obs.text, history=rec.trajectory, goal_experience=goal,
            process_experience=process, max_plan_actions=self.cfg.max_plan_actions, image=image,
        )
        request = self.calls.request(
            "planner", messages, call_key=f"planner:{index}", max_tokens=self.cfg.planner_max_tokens,
            json_schema=planner_schema(len(self.actions), self.cfg.max_plan_actions),
        )
        result = await self.calls.ask(request)
        rec.planner_calls += 1
        plan_rec = self._plan_record(index, result, goal, process, seconds)
        try:
            plan = parse_plan(result.text)
        except PlanParseError as exc:
            plan_rec.status, plan_rec.error, plan_rec.raw = "malformed", str(exc), result.text
            rec.planner_output_errors += 1
            return await self._unusable_output(index)
        plan_rec.language_plan, plan_rec.n_actions = plan.language_plan, len(plan.actions)
        if plan.empty:
            plan_rec.status = "empty"
            rec.empty_plans += 1
            if self.policy == POLICY_RANDOM:
                return await self._unusable_output(index)
            return self._end("empty_plan")
        actions = screen_ids(plan, len(self.actions), self.policy)
        if not actions:
            plan_rec.status, plan_rec.raw = "invalid_id", result.text
            return await self._unusable_output(index)
        await self._execute(index, actions)

    def _plan_record(
        self, index: int, result: ChatResult, goal: list[Any], process: list[Any], seconds: float | None
    ) -> PlanRecord:
        rec = self.record
        plan_rec = PlanRecord(
            index=index, env_step=rec.steps, status="ok",
            retrieved_process=[e.id for e in process], retrieved_goal=[e.id for e in goal],
            retrieval_seconds=round(seconds or 0.0, 9),
            tokens=TokenCount(prompt=result.prompt_tokens, completion=result.completion_tokens),
            latency_s=round(result.latency_s, 6),
        )
        rec.plans.append(plan_rec)
        if seconds is not None:
            rec.retrieval_seconds.append(round(seconds, 9))
        for entry_id in plan_rec.retrieved_goal + plan_rec.retrieved_process:
            if entry_id not in rec.retrieved_ids:
                rec.retrieved_ids.append(entry_id)
        return plan_rec

    async def _unusable_output(self, index: int) -> None:
        """EB-Navigation: one random action. EB-ALFRED/Habitat: one invalid action, no env step."""
        if self.policy == POLICY_RANDOM:
            action_id = self._random_action(f"random:{index}")
            return await self._execute(index, (PlannedAction(action_id, "", None, False),), substituted=True)
        rec = self.record
        self.invalid += 1
        rec.invalid_actions += 1
        rec.trajectory.append(StepRecord(
            step=rec.steps, plan_index=index, env_step=False, action_id=-1, action_name=INVALID_OUTPUT_NAME,
            feedback="", progress=rec.progress, success=rec.success, invalid=True,
        ))
        if self.env.max_invalid is not None and self.invalid >= self.env.max_invalid:
            self._end("max_invalid")

    def _random_action(self, key: str) -> int:
        return random.Random(derive_seed(self.ctx.seed, self.task.index, key)).randrange(len(self.actions))

    # -- acting -------------------------------------------------------------------------------------

    async def _execute(
        self, index: int, actions: tuple[PlannedAction, ...], *, substituted: bool = False
    ) -> None:
        checks: list[_Check] = []
        for pos, planned in enumerate(actions):
            step = self._step(index, pos, planned, substituted)
            if self._should_verify(pos, step):
                checks.append(_Check(step, self._before, self.obs, self.record.trajectory[:-1]))
            if self.done or step.invalid:
                break
        await self._verify_all(checks)

    def _step(self, index: int, pos: int, planned: PlannedAction, substituted: bool) -> StepRecord:
        rec, action_id = self.record, planned.action_id
        if not 0 <= action_id < len(self.actions):  # only under the random policy (EB-Navigation's env)
            action_id, substituted = self._random_action(f"substitute:{index}:{pos}"), True
        t0 = time.perf_counter()
        result = self.env.step(action_id)
        env_seconds = time.perf_counter() - t0
        name = self.actions[action_id]
        written = planned.action_name.strip()
        step = StepRecord(
            step=rec.steps + 1, plan_index=index, action_id=action_id, action_name=name,
            planned_name=written if written and written != name else None, substituted=substituted,
            feedback=result.feedback, predicted_state=None if substituted else planned.predicted_state,
            skipped=planned.skipped and not substituted, progress=result.progress, success=result.success,
            invalid=result.invalid, done=result.done, env_seconds=round(env_seconds, 9),
        )
        rec.trajectory.append(step)
        rec.steps, rec.progress, rec.success = step.step, result.progress, result.success
        self._before, self.obs = self.obs, result.observation
        if result.invalid:
            self.invalid += 1
            rec.invalid_actions += 1
        if result.done:
            self._end(result.end_reason or self._inferred_end(result.success))
        elif self.env.max_invalid is not None and self.invalid >= self.env.max_invalid:
            self._end("max_invalid")
        return step

    def _inferred_end(self, success: bool) -> str:
        if success:
            return "success"
        return "max_steps" if self.record.steps >= self.env.max_steps else "env_done"

    def _should_verify(self, pos: int, step: StepRecord) -> bool:
        if not self.cfg.verifier or step.substituted or step.skipped or not step.predicted_state:
            return False
        return self.cfg.verify == "every" or pos == 0

    # -- verifying and learning ---------------------------------------------------------------------

    async def _verify_all(self, checks: list[_Check]) -> None:
        if not checks:
            return
        produced = await asyncio.gather(*(self._verify(c) for c in checks))
        await self._remember([entry for entries in produced for entry in entries])

    async def _verify(self, check: _Check) -> list[Any]:
        step = check.step
        state = await self.abstractor.abstract(check.before, check.after, step.action_name,
                                               call_key=f"summarizer:{step.step}")
        self._book(step, "summarizer", state.result)
        assert step.predicted_state is not None
        verdict = await self.judge.judge(action=step.action_name, predicted=step.predicted_state,
                                         actual=state.after, feedback=step.feedback, call_key=f"judge:{step.step}")
        self._book(step, "judge", verdict.result)
        step.verified, step.actual_state = True, state.after
        step.judge_verdict, step.judge_reason, step.judge_unparseable = (
            verdict.verdict, verdict.reason, verdict.unparseable)
        if verdict.match or not self.cfg.process_experience or self.ctx.memory is None:
            return []
        reflection = await self.reflector.reflect(
            instruction=self.task.instruction, history=format_history(check.history, self.actions),
            action=step.action_name, state_before=state.before, predicted=step.predicted_state,
            actual=state.after, feedback=step.feedback, judge_reason=verdict.reason,
            call_key=f"reflector:{step.step}",
        )
        self._book(step, "reflector", reflection.result)
        step.rules = list(reflection.rules)
        return [self._entry("process", rule, step) for rule in reflection.rules]

    async def _distill(self) -> None:
        result = await self.distiller.distill(instruction=self.task.instruction, task_type=self.task.task_type,
                                              steps=self.record.trajectory, call_key="distiller")
        if result.workflow:
            await self._remember([self._entry("goal", result.workflow, None)])

    def _entry(self, partition: str, text: str, step: StepRecord | None) -> Any:
        from worldmind_local.memory import ExperienceEntry

        task, ids = self.task, self.ctx.model_ids
        return ExperienceEntry(
            partition=partition, text=text, instruction=task.instruction, benchmark=task.benchmark,
            subset=task.subset, episode=task.index, task_id=task.id,
            step=step.step if step else None, action=step.action_name if step else None,
            predicted_state=step.predicted_state if step else None,
            actual_state=step.actual_state if step else None, judge_reason=step.judge_reason if step else None,
            planner_model=ids.get("planner", ""), judge_model=ids.get("judge", ""), run_id=self.ctx.run_id,
        )

    async def _remember(self, entries: list[Any]) -> None:
        """Embed, then add in order (exactly `memory.add`), keeping the embedded entries: the record
        stores them with their vectors so the runner can replay the memory without re-embedding."""
        memory = self.ctx.memory
        if not entries or memory is None:
            return
        entries = await memory.embed(entries)
        kept = [memory.add_embedded(entry) for entry in entries]
        for entry, was_kept in zip(entries, kept, strict=True):
            self.record.experience.append({**entry.model_dump(mode="json"), "kept": bool(was_kept)})

    @staticmethod
    def _book(step: StepRecord, role: str, result: ChatResult | None) -> None:
        if result is None:
            return
        step.tokens.setdefault(role, TokenCount()).add(result.prompt_tokens, result.completion_tokens)
        step.latency_s[role] = round(step.latency_s.get(role, 0.0) + result.latency_s, 6)
