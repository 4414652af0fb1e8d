"""The generic episode driver: EmbodiedBench's evaluator protocol, once, for every method.

Per planning step the method proposes a plan (`Method.plan`); the driver screens its ids, executes the
actions in order until the first invalid one, the end of the plan or the end of the episode, and
re-plans with the history (EB @ b247936, `evaluator/eb_alfred_evaluator.py::evaluate`, the Habitat and
Navigation evaluators alike). The limits are the env's (30 steps / 10 invalid actions on EB-ALFRED and
EB-Habitat, 20 steps on EB-Navigation). An output the planner could not make usable follows the
benchmark adapter's `unusable_output` policy:

- `invalid` (EB-ALFRED, EB-Habitat): an unparseable output is one invalid action without an env step
  and without a history line; an empty plan ends the episode; the plan is cut before its first
  out-of-range id (a first id out of range makes the whole output one invalid action).
- `random` (EB-Navigation): an unparseable output or an empty plan executes one random action
  (seeded, so runs repeat); an out-of-range id goes to the env, which answers as EB's env does.

The driver also decides what the planner may see (`Episode.planner_view`), so no method can show a
model more than the benchmark's protocol allows without the labelled `observation` option.
"""

from __future__ import annotations

import random
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from models.base import ContextLengthError
from worldmind_local.agent.calls import ModelCalls, backend_for, derive_seed, has_vision
from worldmind_local.agent.plan import (
    POLICY_RANDOM,
    PlannedAction,
    screen_ids,
)
from worldmind_local.env import Env, Observation, Task
from worldmind_local.envworkers import EnvWorkerError
from worldmind_local.records import EpisodeRecord, PlanRecord, StepRecord, TokenCount, taxonomy_label

if TYPE_CHECKING:
    from worldmind_local.methods.base import EpisodeContext, Method, Proposal

__all__ = ["Episode", "EpisodeOutcome", "ExecutedAction", "run_episode", "resolve_observation",
           "INVALID_OUTPUT_NAME"]

INVALID_OUTPUT_NAME = "invalid action"  # EB's episode-log description of an unusable planner output


@dataclass(slots=True)
class ExecutedAction:
    """One executed action, as a method's `after_step` hook sees it."""

    step: StepRecord
    planned: PlannedAction
    position: int                  # position in its plan
    before: Observation
    after: Observation
    history: list[StepRecord]      # the trajectory before this action


@dataclass
class EpisodeOutcome:
    """What a method returns for one episode: its record and the experience it produced (entries the
    runner commits to the stream's memory; the method never writes memory itself)."""

    record: EpisodeRecord
    experience: list[Any] = field(default_factory=list)


def resolve_observation(requested: str, *, env_images: bool, planner_vision: bool | None,
                        text_stand_in: bool) -> str:
    """What the planner is shown: `image`, `none` (EB's language-only mode), `description` (EB-Navigation's
    text stand-in for its image for text planners) or `symbolic` (the twin's perfect abstract state,
    only when asked for)."""
    if requested == "symbolic":
        return "symbolic"
    if requested == "none":
        return "none"
    if requested == "image":
        if planner_vision is False:
            raise ValueError("observation='image' needs a vision-language planner")
        if not env_images:
            raise ValueError("observation='image': this env renders no images (use 'none' or 'symbolic')")
        return "image"
    if requested != "auto":
        raise ValueError(f"unknown observation mode {requested!r}; use auto|image|none|symbolic")
    if planner_vision and env_images:
        return "image"
    return "description" if text_stand_in else "none"


class Episode:
    """The state of one episode, shared by the driver and the method's hooks."""

    def __init__(self, task: Task, env: Env, ctx: EpisodeContext, method_name: str) -> None:
        self.task, self.env, self.ctx, self.config = task, env, ctx, ctx.config
        self.record = EpisodeRecord(
            task_id=task.id, benchmark=task.benchmark, subset=task.subset, index=task.index,
            instruction=task.instruction, task_type=task.task_type, method=method_name, run_id=ctx.run_id,
            seed=ctx.seed, model_ids=dict(ctx.model_ids), config=ctx.config.model_dump(mode="json"),
        )
        self.calls = ModelCalls(ctx.models, self.record, seed=ctx.seed, task_index=task.index,
                                temperature=ctx.config.temperature)
        self.adapter = ctx.adapter if ctx.adapter is not None else _adapter(env.benchmark)
        self.experience: list[Any] = []          # what the method produced, for the runner to commit
        self.state: dict[str, Any] = {}          # the method's scratch space for this episode
        self.actions: list[str] = []
        self.obs: Observation | None = None
        self.observation_mode = "none"
        self.invalid = 0
        self.done = False

    @property
    def trajectory(self) -> list[StepRecord]:
        return self.record.trajectory

    def planner_view(self) -> tuple[str | None, Any | None]:
        """(text, image) the planner may see now, by the resolved observation mode."""
        assert self.obs is not None
        mode = self.observation_mode
        if mode == "image":
            return None, self.obs.image
        if mode in ("description", "symbolic"):
            return self.obs.text, None
        return None, None

    def end(self, reason: str) -> None:
        self.done = True
        self.record.end_reason = reason


def _adapter(benchmark: str) -> Any:
    from worldmind_local.registry import BENCHMARKS

    return BENCHMARKS.get(benchmark) if benchmark in BENCHMARKS else None


async def run_episode(method: Method, task: Task, env: Env, ctx: EpisodeContext) -> EpisodeOutcome:
    """Run one episode of `task` in `env` with `method`; never writes memory."""
    ep = Episode(task, env, ctx, method.name)
    rec = ep.record
    t0 = time.perf_counter()
    ep.obs = await _reset(env, task)
    ep.actions = list(env.actions)
    ep.observation_mode = resolve_observation(
        ctx.config.observation, env_images=ep.obs.image is not None,
        planner_vision=has_vision(backend_for(ctx.models, "planner")),
        text_stand_in=bool(ep.adapter is not None and ep.adapter.text_stand_in_for_image),
    )
    rec.observation = ep.observation_mode
    policy = ep.adapter.unusable_output if ep.adapter is not None else "invalid"
    try:
        await method.start(ep)
        planner_limit = env.max_steps + (env.max_invalid or env.max_steps) + 1
        while not ep.done:
            if rec.planner_calls >= planner_limit:
                ep.end("planner_limit")
                break
            await _planning_step(method, ep, policy)
        await method.finish(ep)
    except EnvWorkerError as exc:  # the env's worker died or hung and the failure policy gave up
        rec.error = f"{type(exc).__name__}: {exc}"
        rec.end_reason = "error"
    except ContextLengthError as exc:  # deterministic: the episode outgrew the model's context
        rec.error = str(exc)
        if not rec.success:  # a success stays a success even if its distillation did not fit
            rec.end_reason = "context_length"
    ep.calls.sort_calls()
    rec.taxonomy = taxonomy_label(rec.success, rec.end_reason)
    rec.wall_seconds = round(time.perf_counter() - t0, 6)
    return EpisodeOutcome(rec, ep.experience)


async def _planning_step(method: Method, ep: Episode, policy: str) -> None:
    rec, index = ep.record, len(ep.record.plans)
    proposal = await method.plan(ep)
    rec.planner_calls += 1
    plan_rec = _plan_record(ep, index, proposal)
    plan = proposal.plan
    if plan is None:
        plan_rec.status, plan_rec.error, plan_rec.raw = "malformed", proposal.error, proposal.raw
        rec.planner_output_errors += 1
        return await _unusable_output(method, ep, index, policy)
    plan_rec.language_plan, plan_rec.n_actions = plan.language_plan, len(plan.actions)
    if plan.empty:
        plan_rec.status = "empty"
        rec.empty_plans += 1
        if policy == POLICY_RANDOM:
            return await _unusable_output(method, ep, index, policy)
        return ep.end("empty_plan")
    actions = screen_ids(plan, len(ep.actions), policy)  # type: ignore[arg-type]
    if not actions:
        plan_rec.status, plan_rec.raw = "invalid_id", proposal.raw
        return await _unusable_output(method, ep, index, policy)
    await _execute(method, ep, index, actions)


def _plan_record(ep: Episode, index: int, proposal: Proposal) -> PlanRecord:
    result = proposal.result
    plan_rec = PlanRecord(
        index=index, env_step=ep.record.steps, status="ok", extra=dict(proposal.extra),
        tokens=TokenCount(prompt=result.prompt_tokens if result else 0,
                          completion=result.completion_tokens if result else 0),
        latency_s=round(result.latency_s, 6) if result else 0.0,
    )
    ep.record.plans.append(plan_rec)
    return plan_rec


async def _unusable_output(method: Method, ep: Episode, index: int, policy: str) -> None:
    """EB-Navigation: one random action. EB-ALFRED/Habitat: one invalid action, no env step."""
    if policy == POLICY_RANDOM:
        action_id = random.Random(derive_seed(ep.ctx.seed, ep.task.index, f"random:{index}")).randrange(
            len(ep.actions))
        return await _execute(method, ep, index, (PlannedAction(action_id, "", None, False),), substituted=True)
    rec = ep.record
    ep.invalid += 1
    rec.invalid_actions += 1
    rec.trajectory.append(StepRecord(
        step=rec.steps, plan_index=index, env_step=False, action_id=-1, action_name=INVALID_OUTPUT_NAME,
        feedback="", progress=rec.progress, success=rec.success, invalid=True,
    ))
    if ep.env.max_invalid is not None and ep.invalid >= ep.env.max_invalid:
        ep.end("max_invalid")


async def _execute(method: Method, ep: Episode, index: int, actions: tuple[PlannedAction, ...], *,
                   substituted: bool = False) -> None:
    for pos, planned in enumerate(actions):
        before = ep.obs
        history = list(ep.record.trajectory)
        step = await _step(ep, index, planned, substituted)
        assert before is not None and ep.obs is not None
        method.after_step(ep, ExecutedAction(step, planned, pos, before, ep.obs, history))
        if ep.done or step.invalid:
            break
    await method.after_plan(ep)


async def _reset(env: Env, task: Task) -> Observation:
    """`env.areset` where the env lives off the event loop (a worker process, a Ray actor), else reset."""
    areset = getattr(env, "areset", None)
    return await areset(task) if areset is not None else env.reset(task)


async def _step(ep: Episode, index: int, planned: PlannedAction, substituted: bool) -> StepRecord:
    rec, action_id = ep.record, planned.action_id
    t0 = time.perf_counter()
    astep = getattr(ep.env, "astep", None)
    # an out-of-range id reaches only a `random`-policy env, as in EB
    result = await astep(action_id) if astep is not None else ep.env.step(action_id)
    env_seconds = time.perf_counter() - t0
    in_range = 0 <= action_id < len(ep.actions)
    name = ep.actions[action_id] if in_range else f"action id {action_id} (out of range)"
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
    ep.obs = result.observation
    if result.invalid:
        ep.invalid += 1
        rec.invalid_actions += 1
    if result.done:
        ep.end(result.end_reason or _inferred_end(ep, result.success))
    elif ep.env.max_invalid is not None and ep.invalid >= ep.env.max_invalid:
        ep.end("max_invalid")
    return step


def _inferred_end(ep: Episode, success: bool) -> str:
    if success:
        return "success"
    return "max_steps" if ep.record.steps >= ep.env.max_steps else "env_done"
