"""Replay fixed action plans on any benchmark's env: the fidelity check and the expert demo.

Input lines are `{"subset", "index", "actions": [names]}` (index = position in the subset's list);
each produces one output line `{"subset", "index", "success", "progress", "steps", "invalid",
"feedback", "end_reason"}`. Nothing here knows a benchmark: tasks come from `data.Suite`, envs from the
adapter, and every check goes through the Env contract. A bad line (not JSON, unknown subset, index
out of range, an action name outside the episode's action space) becomes an output line with an
`"error"` and the run goes on. Actions after the episode ends are not run.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, TextIO

from worldmind_local.data import Suite, adapter
from worldmind_local.env import Env, Task, TaskDataError, UnknownActionError

__all__ = ["PlanError", "replay_episode", "replay_lines", "expert_lines", "SubsetScore", "Replayer"]


class PlanError(ValueError):
    """A plan line that cannot be run (its message goes into the output line)."""


def replay_episode(env: Env, task: Task, actions: list[str]) -> dict[str, Any]:
    """Run `actions` from the task's start; stops at the end of the episode or an unknown action."""
    env.reset(task)
    out: dict[str, Any] = {"subset": task.subset, "index": task.index, "success": False, "progress": 0.0,
                           "steps": 0, "invalid": 0, "feedback": [], "end_reason": None}
    for k, name in enumerate(actions):
        if not isinstance(name, str):
            out["error"] = f"action {k} is not a string: {name!r}"
            break
        try:
            action_id = env.action_id(name)
        except UnknownActionError as exc:
            out["error"] = f"action {k} ({name!r}) is not in the action space: {exc}"
            break
        result = env.step(action_id)
        out["steps"] += 1
        out["invalid"] += int(result.invalid)
        out["feedback"].append(result.feedback)
        out["success"], out["progress"] = bool(result.success), float(result.progress)
        if result.done:
            out["end_reason"] = result.end_reason
            break
    return out


MAX_PLAN_LINE_CHARS = 4_000_000  # a plan of ~100k actions; longer lines are refused, not parsed


def _parse(line: str, lineno: int) -> tuple[str, int, list[str]]:
    """Total: any line gives (subset, index, actions) or a PlanError (never RecursionError, the
    int-digit ValueError or a UnicodeError), bounded in size and nesting."""
    from worldmind_local.agent.jsonparse import parse_json  # lazy: the agent package is not light
    from worldmind_local.agent.plan import PlanParseError

    try:
        line.encode("utf-8")
    except UnicodeEncodeError:  # undecodable bytes arrive as surrogate escapes (see cli/replay.py)
        raise PlanError(f"line {lineno}: not UTF-8 text") from None
    try:
        obj = parse_json(line, max_chars=MAX_PLAN_LINE_CHARS)
    except PlanParseError as exc:
        raise PlanError(f"line {lineno}: {exc}") from None
    if not isinstance(obj, dict):
        raise PlanError(f"line {lineno}: expected an object with subset, index and actions")
    subset, index, actions = obj.get("subset"), obj.get("index"), obj.get("actions")
    if not isinstance(subset, str):
        raise PlanError(f"line {lineno}: 'subset' must be a string")
    if not isinstance(index, int) or isinstance(index, bool):
        raise PlanError(f"line {lineno}: 'index' must be an integer")
    if not isinstance(actions, list):
        raise PlanError(f"line {lineno}: 'actions' must be a list of action names")
    return subset, index, actions


@dataclass
class SubsetScore:
    """Success rate (SR) and goal-condition rate (GC, mean final progress) of one subset."""

    episodes: int = 0
    successes: int = 0
    progress: float = 0.0
    errors: int = 0

    def add(self, line: dict[str, Any]) -> None:
        self.episodes += 1
        self.successes += int(bool(line.get("success")))
        self.progress += float(line.get("progress", 0.0))
        self.errors += int("error" in line)

    @property
    def sr(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0

    @property
    def gc(self) -> float:
        return self.progress / self.episodes if self.episodes else 0.0


@dataclass
class Replayer:
    """Runs plan lines against one suite and one env kind, keeping per-subset scores."""

    suite: Suite
    env_kind: str = "twin"
    scores: dict[str, SubsetScore] = field(default_factory=dict)
    skipped: int = 0  # lines that named no episode (bad JSON, unknown subset, index out of range)
    _tasks: dict[str, list[Task]] = field(default_factory=dict)
    _env: Env | None = None

    def tasks(self, subset: str) -> list[Task]:
        if subset not in self._tasks:
            self._tasks[subset] = self.suite.tasks(subset)
        return self._tasks[subset]

    def env(self) -> Env:
        if self._env is None:
            self._env = adapter(self.suite.benchmark).make_env(self.env_kind)
        return self._env

    def run_line(self, line: str, lineno: int) -> dict[str, Any]:
        """One plan line -> one result line (with "error" when it could not be run as asked)."""
        try:
            subset, index, actions = _parse(line, lineno)
        except PlanError as exc:
            self.skipped += 1
            return {"line": lineno, "error": str(exc)}
        base = {"subset": subset, "index": index}
        try:
            tasks = self.tasks(subset)
        except (ValueError, TaskDataError, FileNotFoundError) as exc:
            self.skipped += 1
            return {**base, "line": lineno, "error": str(exc)}
        if not 0 <= index < len(tasks):
            self.skipped += 1
            return {**base, "line": lineno, "error": f"index {index} out of range 0..{len(tasks) - 1} for subset {subset!r}"}
        try:
            result = replay_episode(self.env(), tasks[index], actions)
        except (ValueError, RuntimeError) as exc:  # the env refused this task; the run goes on
            result = {**base, "success": False, "progress": 0.0, "steps": 0, "invalid": 0, "feedback": [],
                      "line": lineno, "error": f"{type(exc).__name__}: {exc}"}
        self.scores.setdefault(subset, SubsetScore()).add(result)
        return result

    def close(self) -> None:
        if self._env is not None:
            self._env.close()


def replay_lines(replayer: Replayer, lines: Iterable[str], out: TextIO, tick: Callable[[], None] | None = None) -> int:
    """Replay every non-blank line, writing one JSON line each; returns the number of lines written."""
    written = 0
    for lineno, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        out.write(json.dumps(replayer.run_line(line, lineno)) + "\n")
        out.flush()
        written += 1
        if tick:
            tick()
    return written


def expert_lines(replayer: Replayer, subsets: Iterable[str]) -> Iterator[str]:
    """Plan lines that replay each task's own expert plan (tasks without one get an empty plan)."""
    for subset in subsets:
        for task in replayer.tasks(subset):
            yield json.dumps({"subset": subset, "index": task.index, "actions": list(task.expert_plan or ())})
