"""The environment seam: tasks, observations, step results, and what a benchmark adapter provides.

Every benchmark folder (`benchmarks/eb_*`) implements `BenchmarkAdapter`; every simulator backend
(the symbolic `twin`, or the real `embodiedbench` wrapper) implements `Env`. Methods and the runner
only ever see these types, so a memory or a prompt built on the twin carries over to the real
simulator unchanged.

The hot path (a twin step) must stay in the tens of microseconds, so `Observation` renders its text
and state lazily: an environment hands over a snapshot plus a function, and the text is built only
when somebody reads it (the judge reads one per verified action, not one per step).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

__all__ = [
    "Task",
    "Observation",
    "StepResult",
    "Env",
    "BenchmarkAdapter",
    "TaskDataError",
    "UnknownActionError",
    "ExampleAction",
    "WorkedExample",
    "lookup_action",
]


class TaskDataError(ValueError):
    """A data file is malformed: the message names the file and the field."""

    def __init__(self, path: Path | str, field_name: str, problem: str) -> None:
        self.path = str(path)
        self.field = field_name
        super().__init__(f"{path}: field {field_name!r}: {problem}")


class UnknownActionError(KeyError):
    """An action name that is not in the episode's action space."""

    def __str__(self) -> str:  # KeyError quotes its message; we want it readable
        return str(self.args[0]) if self.args else "unknown action"


def lookup_action(ids: dict[str, int], name: str, *, benchmark: str, task: Task | None) -> int:
    """The id of an action name in an episode's action space, or UnknownActionError naming the action,
    the benchmark and the task. Every env (the three twins and the three EmbodiedBench wrappers) answers
    `Env.action_id` through this one function."""
    try:
        return ids[name]
    except KeyError:
        where = task.id if task is not None else "(none: reset first)"
        raise UnknownActionError(f"action {name!r} is not in the {benchmark} action space of task {where}") from None


@dataclass(frozen=True, slots=True)
class Task:
    """One episode's task.

    `index` is the position in the subset's list (EmbodiedBench's episode number). `payload` is the
    benchmark-specific record (an EB-ALFRED task record, an EB-Habitat episode, ...) that the
    benchmark's own env knows how to read; nothing outside the benchmark looks inside it.
    """

    id: str
    benchmark: str
    subset: str
    index: int
    instruction: str
    task_type: str
    payload: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    expert_plan: tuple[str, ...] | None = field(default=None, repr=False, compare=False)


class Observation:
    """What the agent gets after reset or a step.

    `text` is the abstract state s-bar: what a perfect state abstractor would say (location, held
    object, visible objects and their states). `image` is an optional PIL image. `state` is a
    structured snapshot (JSON-serialisable dict) for logs and tests. Text and state may be given
    directly or as zero-argument functions evaluated at most once; an env that passes functions
    must bind them to an immutable snapshot of the state at that step.
    """

    __slots__ = ("_text", "_text_fn", "_state", "_state_fn", "image")

    def __init__(
        self,
        text: str | Callable[[], str],
        *,
        state: dict[str, Any] | Callable[[], dict[str, Any]] | None = None,
        image: Any | None = None,
    ) -> None:
        self._text: str | None
        self._text_fn: Callable[[], str] | None
        self._state: dict[str, Any] | None
        self._state_fn: Callable[[], dict[str, Any]] | None
        if callable(text):
            self._text, self._text_fn = None, text
        else:
            self._text, self._text_fn = text, None
        if callable(state):
            self._state, self._state_fn = None, state
        else:
            self._state, self._state_fn = state if state is not None else {}, None
        self.image = image

    @property
    def text(self) -> str:
        if self._text is None:
            assert self._text_fn is not None
            self._text, self._text_fn = self._text_fn(), None
        return self._text

    @property
    def state(self) -> dict[str, Any]:
        if self._state is None:
            assert self._state_fn is not None
            self._state, self._state_fn = self._state_fn(), None
        return self._state

    def __repr__(self) -> str:
        return f"Observation(text={self.text!r})"


@dataclass(slots=True)
class StepResult:
    """The outcome of one action, with EmbodiedBench's exact feedback string.

    `progress` is EmbodiedBench's task_progress after this step (the episode's GC is the last
    step's value). `done` is set on success, on the step limit and on the invalid-action limit;
    `end_reason` then says which ("success", "max_steps", "max_invalid", or a benchmark's own).
    """

    feedback: str
    success: bool
    progress: float
    invalid: bool
    done: bool
    observation: Observation
    end_reason: str | None = None
    info: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class ExampleAction:
    """One action of a worked in-context example: the id in that example's own action list, the
    action's name, the state the agent should predict after it (the skip string when the target is
    not grounded yet), and the env feedback it received."""

    action_id: int
    action_name: str
    predicted_state: str
    feedback: str


@dataclass(frozen=True, slots=True)
class WorkedExample:
    """A few-shot example built from an expert plan run through the twin (never from an evaluated
    episode). Methods render it in their own format: WorldMind shows `predicted_state`, EB's ReAct
    format shows `reasoning` and `language_plan` and the actions without predictions."""

    task_id: str
    instruction: str
    reasoning: str
    language_plan: str
    actions: tuple[ExampleAction, ...]


@runtime_checkable
class Env(Protocol):
    """One simulator backend of one benchmark. `actions` is valid after `reset` (the id is the position)."""

    benchmark: str
    actions: list[str]
    max_steps: int
    max_invalid: int | None

    def reset(self, task: Task) -> Observation: ...

    def step(self, action_id: int) -> StepResult: ...

    def action_id(self, name: str) -> int:
        """The id of an action name; raises UnknownActionError naming the action and the task."""
        ...

    def close(self) -> None: ...


@runtime_checkable
class BenchmarkAdapter(Protocol):
    """What each `benchmarks/eb_*` package exposes as `ADAPTER`."""

    name: str
    subsets: tuple[str, ...]
    default_top_k: int
    default_n_shots: int
    unusable_output: str            # "invalid" | "random": EB's policy for unusable planner output
    text_stand_in_for_image: bool   # text planners see the env's text description (EB-Navigation)

    def load_tasks(self, data_dir: Path, subset: str) -> list[Task]:
        """EmbodiedBench's episodes of one subset, in EmbodiedBench's order. Raises TaskDataError."""
        ...

    def generate_tasks(self, seed: int, subset: str, n: int) -> list[Task]:
        """Procedurally generated tasks in the same record format, deterministic per (seed, subset, n),
        each with `expert_plan` set."""
        ...

    def make_env(self, kind: str = "twin", **options: Any) -> Env:
        """`twin` (symbolic, always available) or `embodiedbench` (real simulator, optional)."""
        ...

    def has_data(self, data_dir: Path) -> bool: ...

    def worked_examples(
        self, n: int, *, data_dir: Path | None = None, exclude: Collection[str] = ()
    ) -> list[WorkedExample]:
        """`min(n, pool size)` few-shot examples (`default_n_shots` is the official count), the same
        for the same arguments: expert plans run on the twin, from the data pack's tasks where
        `data_dir` holds it, else from a generated suite of a seed no evaluation uses. An example
        whose task id or instruction is in `exclude` (the evaluated episode's) is never returned."""
        ...


def plan_names(actions: Sequence[str], ids: Sequence[int]) -> list[str]:
    """Action names of a list of ids (for logs)."""
    return [actions[i] for i in ids]
