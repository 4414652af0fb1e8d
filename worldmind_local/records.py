"""What `episodes.jsonl` holds: one `EpisodeRecord` per finished episode, with every step and plan.

Records are pydantic models so a run can be loaded, validated and diffed (`EpisodeRecord.model_validate`
on a line of episodes.jsonl). `EpisodeRecord` holds what every method has (the task, the outcome, every
plan, step and model call, tokens per role); what only one method counts (WorldMind's judge verdicts,
reflections, distillations) lives in `method_stats`, a dict written from that method's own pydantic
model. `experience` lists the entries the episode produced, WITHOUT embeddings (the stream's memory
dataset holds the vectors) plus `kept` (the runner's commit decision). `calls` lists every model call
with its request key, so any prompt can be read back from the run's cache (`worldmind show`).
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

__all__ = [
    "END_REASONS",
    "TAXONOMY",
    "TokenCount",
    "PlanRecord",
    "StepRecord",
    "EpisodeRecord",
    "taxonomy_label",
    "role_token_map",
    "CallRecord",
]

# Why an episode ended. The env reports the first three; the loop adds the rest.
END_REASONS = (
    "success", "max_steps", "max_invalid", "empty_plan", "planner_limit", "env_done", "context_length", "error",
)
# The paper's error taxonomy (Sec. "Error Analysis"), plus "error" for episodes a backend could not finish.
TAXONOMY = ("success", "invalid_action_end", "step_limit", "wrong_termination", "error")

_ROLES = ("planner", "judge", "reflector", "distiller", "summarizer")


class CallRecord(BaseModel):
    """One model call: its place in the episode (`key`), its role, and the cache key of its request."""

    model_config = ConfigDict(extra="forbid")
    key: str
    role: str
    request: str                                # models.base.request_key(model_id, request)
    model: str = ""
    n: int = 1                                  # generations asked for in this one request (BoN, SimuRA)
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_s: float = 0.0


class TokenCount(BaseModel):
    model_config = ConfigDict(extra="forbid")
    prompt: int = 0
    completion: int = 0

    @property
    def total(self) -> int:
        return self.prompt + self.completion

    def add(self, prompt: int, completion: int) -> None:
        self.prompt += int(prompt)
        self.completion += int(completion)


def role_token_map() -> dict[str, TokenCount]:
    """One zeroed counter per role, so every record has the same keys."""
    return {role: TokenCount() for role in _ROLES}


class PlanRecord(BaseModel):
    """One planner call: what it was shown (retrieved entry ids) and what it answered."""

    model_config = ConfigDict(extra="forbid")
    index: int                                  # 0-based planner call number in the episode
    env_step: int                               # env steps taken before this call
    status: Literal["ok", "empty", "malformed", "invalid_id"]
    language_plan: str = ""
    n_actions: int = 0
    error: str | None = None                    # why the output was malformed
    raw: str | None = None                      # the raw output, kept only when it could not be used
    tokens: TokenCount = Field(default_factory=TokenCount)
    latency_s: float = 0.0
    extra: dict[str, Any] = Field(default_factory=dict)   # the method's part: retrieved ids, candidates, ...


class StepRecord(BaseModel):
    """One executed action (or, for EB-ALFRED/EB-Habitat, one unusable planner output that EB counts
    as an invalid action without stepping the env: `env_step` False, `action_id` -1)."""

    model_config = ConfigDict(extra="forbid")
    step: int                                   # env step number after this action (1-based)
    plan_index: int                             # which PlanRecord produced it
    env_step: bool = True
    action_id: int
    action_name: str
    planned_name: str | None = None             # the name the planner wrote, when it differs
    substituted: bool = False                   # EB-Navigation: a random action stood in for an unusable output
    feedback: str
    predicted_state: str | None = None
    skipped: bool = False                       # prediction is (or cascades from) the skip string
    verified: bool = False
    actual_state: str | None = None
    judge_verdict: Literal["match", "mismatch"] | None = None
    judge_reason: str | None = None
    judge_unparseable: bool = False
    rules: list[str] = Field(default_factory=list)      # the reflector's corrective rules, if any
    progress: float = 0.0
    success: bool = False
    invalid: bool = False
    done: bool = False
    tokens: dict[str, TokenCount] = Field(default_factory=dict)   # judge/reflector/summarizer of this step
    latency_s: dict[str, float] = Field(default_factory=dict)
    env_seconds: float = 0.0


class EpisodeRecord(BaseModel):
    model_config = ConfigDict(extra="forbid")
    # the task
    task_id: str
    benchmark: str
    subset: str
    index: int
    instruction: str
    task_type: str
    # the run
    method: str
    run_id: str = ""
    stream_id: str = ""                         # set by the runner
    wave: list[int] | None = None               # [first episode index, size] when run in a wave (--wave)
    seed: int = 0
    model_ids: dict[str, str] = Field(default_factory=dict)
    config: dict[str, Any] = Field(default_factory=dict)
    # the outcome
    success: bool = False
    progress: float = 0.0                       # GC: the last step's task_progress
    steps: int = 0                              # env steps (EB's num_steps)
    invalid_actions: int = 0                    # EB's num_invalid_actions (includes unusable outputs)
    end_reason: str = "error"
    taxonomy: str = "error"
    error: str | None = None
    observation: str = "none"                   # what the planner was shown: image|none|description|symbolic
    # model usage
    tokens: dict[str, TokenCount] = Field(default_factory=role_token_map)
    latency_s: dict[str, float] = Field(default_factory=dict)
    calls: list[CallRecord] = Field(default_factory=list)
    planner_calls: int = 0
    planner_output_errors: int = 0              # EB's planner_output_error: outputs that were not usable JSON
    empty_plans: int = 0
    # memory (methods with a global memory)
    retrieval_seconds: list[float] = Field(default_factory=list)   # one per retrieval
    retrieved_ids: list[str] = Field(default_factory=list)         # distinct ids, first-seen order
    experience: list[dict[str, Any]] = Field(default_factory=list)  # entries without embeddings, + kept
    method_stats: dict[str, Any] = Field(default_factory=dict)     # the method's own counters
    # the trajectory
    plans: list[PlanRecord] = Field(default_factory=list)
    trajectory: list[StepRecord] = Field(default_factory=list)
    wall_seconds: float = 0.0

    def calls_by_role(self) -> dict[str, int]:
        """How many model calls of each role the episode made (the paper's overhead table)."""
        out: dict[str, int] = {}
        for call in self.calls:
            out[call.role] = out.get(call.role, 0) + 1
        return out

    def add_tokens(self, role: str, prompt: int, completion: int, latency_s: float) -> None:
        self.tokens.setdefault(role, TokenCount()).add(prompt, completion)
        self.latency_s[role] = round(self.latency_s.get(role, 0.0) + float(latency_s), 6)


def taxonomy_label(success: bool, end_reason: str) -> str:
    """Map an episode's end onto the paper's failure categories.

    Invalid-action end = the invalid-action limit; timeout = the step limit; every other way of
    stopping without success (empty plan, a benchmark's own stop) is a wrong termination.
    """
    if success:
        return "success"
    if end_reason == "max_invalid":
        return "invalid_action_end"
    if end_reason == "max_steps":
        return "step_limit"
    if end_reason in ("error", "context_length"):
        return "error"
    return "wrong_termination"
