"""WorldMind (paper Sec. 2, Alg. 1-2) as a method on the generic driver, and its ablations by name.

Hooks, in the order the driver calls them:
- `start`: embed the instruction once; retrieve Process Experience once for the episode (official
  code; `process_retrieval="call"` retrieves on every planner call instead, from the committed memory
  plus the episode's own new rules); build the few-shot examples (never from the evaluated task).
- `plan`: retrieve Goal Experience (every call, self-excluded by identical instruction), optionally
  refine the retrieved experience (official code's refiner, off by default), ask the planner for
  `{language_plan, executable_plan: [{action_id, action_name, predicted_state}]}`, parse it.
- `after_step`: keep the executed action for verification when it carries a real prediction: the
  first action of each plan (`verify="first"`, the official code) or every one.
- `after_plan`: for each kept action, abstract the actual state (the env's abstract-state text on the
  twins, a VLM summary of images with `abstract_with="vlm"`), ask the judge (prediction and actual
  state only; `judge_feedback` adds the env feedback, an option), and on a mismatch ask the reflector
  for rules -> Process Experience.
- `finish`: on success, distill the trajectory (with task_progress increases marked) -> Goal Experience.

The experience goes to `ep.experience`; the runner commits it to the stream's repository after the
episode. Ablations (the paper's tables) are method names, each fixing switches of `WorldMindConfig`:
`worldmind` (Full), `worldmind_goal_only`, `worldmind_process_only`, `worldmind_baseline` (the same
prompt framework with every memory and verification component off), and `worldmind_no_verifier`
(controlled memory ablation: Process Experience kept, no validator, so every checked prediction is
reflected on: what the validator filters is exactly what this row measures).
"""

from __future__ import annotations

import time
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, Field

from worldmind_local.agent.abstractor import StateAbstractor
from worldmind_local.agent.calls import backend_for, has_vision
from worldmind_local.agent.distiller import GoalDistiller
from worldmind_local.agent.driver import Episode, ExecutedAction
from worldmind_local.agent.judge import Judge
from worldmind_local.agent.plan import PlanParseError, parse_plan, planner_schema
from worldmind_local.agent.prompting import (
    format_examples,
    format_experience,
    format_history,
    planner_messages,
)
from worldmind_local.agent.refiner import ExperienceRefiner
from worldmind_local.agent.reflector import Reflector
from worldmind_local.methods.base import BaseMethod, MethodConfig, Proposal
from worldmind_local.records import StepRecord, TokenCount

__all__ = [
    "WorldMindConfig",
    "WorldMindStats",
    "WorldMind",
    "WorldMindGoalOnly",
    "WorldMindProcessOnly",
    "WorldMindNoVerifier",
    "WorldMindBaseline",
    "ABLATIONS",
    "SWITCHES",
]

DEFAULT_TOP_K = 2  # the paper's k where a benchmark adapter sets none


class WorldMindConfig(MethodConfig):
    top_k: int | None = Field(None, ge=0, le=50, description="entries retrieved per partition (default per benchmark)")
    goal_experience: bool = Field(True, description="Goal Experience (distil successes, retrieve workflows)")
    process_experience: bool = Field(True, description="Process Experience (reflect on mismatches)")
    verifier: bool = Field(True, description="the judge (predict-act-verify)")
    verify: Literal["first", "every"] = Field("first", description="verify the first action of each plan or every one")
    abstract_with: Literal["text", "vlm"] = Field("text", description="actual state: env abstract text or VLM summary")
    process_retrieval: Literal["episode", "call"] = Field(
        "episode", description="retrieve Process Experience once per episode (official) or per planner call")
    judge_feedback: bool = Field(False, description="also show the judge the env feedback (not in the paper)")
    refine: bool = Field(False, description="official code's experience refiner before each planner call")
    max_rules: int | None = Field(None, ge=1, le=20, description="cap on rules per reflection (default none)")
    budget_unit: Literal["episodes", "entries"] = Field(
        "episodes", description="unit of --memory-budget: source episodes (paper) or entries")
    judge_max_tokens: int = Field(256, ge=16, le=8192)
    reflector_max_tokens: int = Field(1024, ge=16, le=8192)
    distiller_max_tokens: int = Field(512, ge=16, le=8192)
    summarizer_max_tokens: int = Field(384, ge=16, le=8192)
    refiner_max_tokens: int = Field(768, ge=16, le=8192)


SWITCHES = ("goal_experience", "process_experience", "verifier")


class WorldMindStats(BaseModel):
    """WorldMind's per-episode counters (`EpisodeRecord.method_stats`)."""

    judge_calls: int = 0
    judge_mismatches: int = 0
    judge_unparseable: int = 0
    reflections: int = 0
    reflection_tokens: list[int] = Field(default_factory=list)
    reflector_unparseable: int = 0
    distillations: int = 0
    distillation_tokens: list[int] = Field(default_factory=list)
    distiller_unparseable: int = 0
    summarizer_calls: int = 0
    refiner_calls: int = 0
    refiner_unparseable: int = 0
    examples: int = 0
    actual_state_source: str = "env_abstract_state"


class WorldMind(BaseMethod):
    name: ClassVar[str] = "worldmind"
    description: ClassVar[str] = "WorldMind (Full): Process + Goal Experience, predict-act-verify"
    memory_scope: ClassVar[Any] = "global"
    config_class: ClassVar[type[MethodConfig]] = WorldMindConfig
    config: WorldMindConfig

    # -- memory (the runner owns it; the method says what kind) ----------------------------------

    def new_memory(self, embedder: Any, budget: int | None) -> Any | None:
        from worldmind_local.memory import WorldKnowledgeRepository

        return WorldKnowledgeRepository(embedder, budget=budget, budget_unit=self.config.budget_unit)

    def load_memory(self, path: str, embedder: Any, budget: int | None) -> Any | None:
        from worldmind_local.memory import WorldKnowledgeRepository

        repo = WorldKnowledgeRepository.load(path, embedder, budget=budget, budget_unit=self.config.budget_unit)
        repo.commits = []  # a seed repository's own history is not this stream's
        return repo

    @property
    def _uses_memory(self) -> bool:
        return self.config.goal_experience or self.config.process_experience

    # -- hooks ---------------------------------------------------------------------------------------

    async def start(self, ep: Episode) -> None:
        cfg, bench = self.config, ep.env.benchmark
        stats = WorldMindStats(actual_state_source="vlm_summary" if cfg.abstract_with == "vlm" else "env_abstract_state")
        ep.calls.stats = stats
        summarizer = backend_for(ep.ctx.models, "summarizer")
        if cfg.abstract_with == "vlm" and has_vision(summarizer) is False:
            raise ValueError(f"abstract_with='vlm' needs a vision-language summarizer; "
                             f"{summarizer.model_id} is a text-only model")
        ep.state.update(stats=stats, checks=[], overlay=None)
        ep.state.update(
            abstractor=StateAbstractor(bench, ep.calls, mode=cfg.abstract_with, max_tokens=cfg.summarizer_max_tokens),
            judge=Judge(bench, ep.calls, max_tokens=cfg.judge_max_tokens),
            reflector=Reflector(bench, ep.calls, max_tokens=cfg.reflector_max_tokens, max_rules=cfg.max_rules),
            distiller=GoalDistiller(bench, ep.calls, max_tokens=cfg.distiller_max_tokens),
            refiner=ExperienceRefiner(ep.calls, max_tokens=cfg.refiner_max_tokens),
            top_k=cfg.top_k if cfg.top_k is not None else getattr(ep.adapter, "default_top_k", DEFAULT_TOP_K),
            examples=self._examples(ep),
        )
        ep.state["query"] = await self._embed_query(ep)
        ep.state["process"] = self._retrieve(ep, "process") if cfg.process_retrieval == "episode" else None

    async def plan(self, ep: Episode) -> Proposal:
        cfg, index = self.config, len(ep.record.plans)
        t0 = time.perf_counter()
        goal = self._retrieve(ep, "goal")
        process = ep.state["process"] if ep.state["process"] is not None else self._retrieve(ep, "process")
        seconds = time.perf_counter() - t0
        experience = format_experience(goal, process)
        if cfg.refine and (goal or process):
            refinement = await ep.state["refiner"].refine(
                instruction=ep.task.instruction, goal=goal, process=process, call_key=f"refiner:{index}")
            ep.state["stats"].refiner_calls += 1
            ep.state["stats"].refiner_unparseable += int(refinement.unparseable)
            experience = refinement.text
        text, image = ep.planner_view()
        messages = planner_messages(
            ep.env.benchmark, actions=ep.actions, instruction=ep.task.instruction, history=ep.trajectory,
            observation=text, image=image, experience=experience if self._uses_memory else "",
            examples=ep.state["examples"], max_plan_actions=cfg.max_plan_actions,
        )
        request = ep.calls.request("planner", messages, call_key=f"planner:{index}",
                                   max_tokens=cfg.planner_max_tokens,
                                   json_schema=planner_schema(len(ep.actions), cfg.max_plan_actions))
        result = await ep.calls.ask(request, call_key=f"planner:{index}")
        extra = self._note_retrieval(ep, goal, process, seconds)
        try:
            return Proposal(parse_plan(result.text), result, result.text, extra=extra)
        except PlanParseError as exc:
            return Proposal(None, result, result.text, error=str(exc), extra=extra)

    def after_step(self, ep: Episode, executed: ExecutedAction) -> None:
        cfg, step = self.config, executed.step
        checking = cfg.verifier or (cfg.process_experience and ep.ctx.memory is not None)
        if not checking or step.substituted or step.skipped or not step.predicted_state:
            return
        if cfg.verify == "every" or executed.position == 0:
            ep.state["checks"].append(executed)

    async def after_plan(self, ep: Episode) -> None:
        checks, ep.state["checks"] = ep.state["checks"], []
        if not checks:
            return
        # The checks of one plan run concurrently (the plan cannot change in between), so a batching
        # backend sees them together; their experience is kept in step order.
        produced = await ep.calls.gather(*(self._verify(ep, c) for c in checks))
        entries = [e for batch in produced for e in batch]
        ep.experience.extend(entries)
        if entries and self.config.process_retrieval == "call" and ep.ctx.memory is not None:
            await self._overlay_add(ep, entries)

    async def finish(self, ep: Episode) -> None:
        rec, stats = ep.record, ep.state.get("stats")
        try:
            if rec.success and self.config.goal_experience and ep.ctx.memory is not None:
                result = await ep.state["distiller"].distill(
                    instruction=ep.task.instruction, task_type=ep.task.task_type, steps=rec.trajectory,
                    call_key="distiller")
                if result.workflow:
                    ep.experience.append(_entry(ep, "goal", result.workflow, None))
        finally:
            if stats is not None:
                rec.method_stats = stats.model_dump(mode="json")

    # -- parts ---------------------------------------------------------------------------------------

    def _examples(self, ep: Episode) -> str:
        n = self.config.n_shots
        if n is None:
            n = getattr(ep.adapter, "default_n_shots", 0)
        make = getattr(ep.adapter, "worked_examples", None)
        if not n or make is None:
            return ""
        examples = make(n, data_dir=ep.ctx.data_dir, exclude=(ep.task.id, ep.task.instruction))
        ep.state["stats"].examples = len(examples)
        return format_examples(examples, with_predictions=True)

    async def _embed_query(self, ep: Episode) -> Any:
        memory = ep.ctx.memory
        if memory is None or not self._uses_memory or ep.state["top_k"] == 0:
            return None
        embedder = ep.ctx.embedder or getattr(memory, "embedder", None)
        if embedder is None:
            raise ValueError("EpisodeContext has a memory but no embedder to embed the task instruction")
        return (await embedder.aencode([ep.task.instruction]))[0]

    def _retrieve(self, ep: Episode, partition: str) -> list[Any]:
        cfg, query = self.config, ep.state.get("query")
        wanted = cfg.goal_experience if partition == "goal" else cfg.process_experience
        memory = ep.state.get("overlay") or ep.ctx.memory
        if memory is None or query is None or not wanted:
            return []
        exclude = ep.task.instruction if partition == "goal" else None
        return memory.retrieve(query, partition, ep.state["top_k"], exclude_instruction=exclude)

    def _note_retrieval(self, ep: Episode, goal: list[Any], process: list[Any], seconds: float) -> dict[str, Any]:
        rec = ep.record
        if ep.state.get("query") is None:
            return {}
        rec.retrieval_seconds.append(round(seconds, 9))
        for entry in [*goal, *process]:
            if entry.id not in rec.retrieved_ids:
                rec.retrieved_ids.append(entry.id)
        return {"retrieved_goal": [e.id for e in goal], "retrieved_process": [e.id for e in process],
                "retrieval_seconds": round(seconds, 9)}

    async def _overlay_add(self, ep: Episode, entries: list[Any]) -> None:
        """Per-call process retrieval sees the episode's own new rules: a private copy of the memory
        holds them until the runner commits the episode."""
        if ep.state["overlay"] is None:
            ep.state["overlay"] = ep.ctx.memory.copy()
        overlay = ep.state["overlay"]
        for entry in await overlay.embed(entries):
            overlay.add_embedded(entry)

    async def _verify(self, ep: Episode, check: ExecutedAction) -> list[Any]:
        cfg, step, st = self.config, check.step, ep.state
        state = await st["abstractor"].abstract(check.before, check.after, step.action_name,
                                                call_key=f"summarizer:{step.step}")
        _book(step, "summarizer", state.result)
        assert step.predicted_state is not None
        step.verified, step.actual_state = True, state.after
        if cfg.verifier:
            verdict = await st["judge"].judge(predicted=step.predicted_state, actual=state.after,
                                              feedback=step.feedback if cfg.judge_feedback else None,
                                              call_key=f"judge:{step.step}")
            _book(step, "judge", verdict.result)
            step.judge_verdict, step.judge_reason, step.judge_unparseable = (
                verdict.verdict, verdict.reason, verdict.unparseable)
            if verdict.match:
                return []
            reason = verdict.reason
        else:
            reason = "(no validator: every checked prediction is reflected on)"
        if not cfg.process_experience or ep.ctx.memory is None:
            return []
        reflection = await st["reflector"].reflect(
            instruction=ep.task.instruction, history=format_history(check.history, ep.actions),
            action=step.action_name, state_before=state.before, predicted=step.predicted_state,
            actual=state.after, feedback=step.feedback, judge_reason=reason,
            call_key=f"reflector:{step.step}",
        )
        _book(step, "reflector", reflection.result)
        step.rules = list(reflection.rules)
        return [_entry(ep, "process", rule, step) for rule in reflection.rules]


def _entry(ep: Episode, partition: str, text: str, step: StepRecord | None) -> Any:
    from worldmind_local.memory import ExperienceEntry

    task, ids = ep.task, ep.ctx.model_ids
    return ExperienceEntry(
        partition=partition, text=text, instruction=task.instruction, benchmark=task.benchmark,
        subset=task.subset, episode=task.index, task_id=task.id,
        step=step.step if step else None, action=step.action_name if step else None,
        predicted_state=step.predicted_state if step else None,
        actual_state=step.actual_state if step else None, judge_reason=step.judge_reason if step else None,
        planner_model=ids.get("planner", ""), judge_model=ids.get("judge", ""), run_id=ep.ctx.run_id,
    )


def _book(step: StepRecord, role: str, result: Any) -> None:
    if result is None:
        return
    step.tokens.setdefault(role, TokenCount()).add(result.prompt_tokens, result.completion_tokens)
    step.latency_s[role] = round(step.latency_s.get(role, 0.0) + result.latency_s, 6)


class WorldMindGoalOnly(WorldMind):
    name = "worldmind_goal_only"
    description = "ablation 'Goal only': Goal Experience, no Process Experience, no judge"
    fixed = {"goal_experience": True, "process_experience": False, "verifier": False}


class WorldMindProcessOnly(WorldMind):
    name = "worldmind_process_only"
    description = "ablation 'Process only' (= WM w/o Goal): Process Experience with the judge, no Goal Experience"
    fixed = {"goal_experience": False, "process_experience": True, "verifier": True}


class WorldMindNoVerifier(WorldMind):
    name = "worldmind_no_verifier"
    description = "controlled ablation 'WM w/o Verifier': both experiences, every checked prediction reflected"
    fixed = {"goal_experience": True, "process_experience": True, "verifier": False}


class WorldMindBaseline(WorldMind):
    name = "worldmind_baseline"
    description = "ablation 'Baseline': WorldMind's prompt framework, no memory, no verification"
    fixed = {"goal_experience": False, "process_experience": False, "verifier": False}
    memory_scope = "episodic"

    def new_memory(self, embedder: Any, budget: int | None) -> Any | None:
        return None

    def load_memory(self, path: str, embedder: Any, budget: int | None) -> Any | None:
        return None


WorldMind.fixed = {"goal_experience": True, "process_experience": True, "verifier": True}

ABLATIONS: dict[str, type[WorldMind]] = {
    cls.name: cls for cls in (WorldMind, WorldMindGoalOnly, WorldMindProcessOnly, WorldMindNoVerifier,
                              WorldMindBaseline)
}


def canonical_variant(switches: dict[str, bool]) -> str | None:
    """The ablation name whose fixed switches equal `switches`, if any (one spelling per variant)."""
    for name, cls in ABLATIONS.items():
        if all(cls.fixed.get(k) == switches.get(k) for k in SWITCHES):
            return name
    return None
