"""The symbolic EB-ALFRED twin: EmbodiedBench's interface (actions, feedback, limits, success and
task_progress) over a symbolic scene, in microseconds per step.

Per step: run the skill (skills.py), count the step and, on failure, the invalid action; recompute
(s, ts) from the current state when the state changed; end the episode on success, at 30 steps or at
10 invalid actions, as EBAlfEnv does. The observation's text and state are rendered lazily from an
immutable snapshot of this step (see world.py for the copy-on-write).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

from benchmarks.eb_alfred.goals import conditions_met
from benchmarks.eb_alfred.scene import Scene, cached_scene
from benchmarks.eb_alfred.skills import Skills
from benchmarks.eb_alfred.state_text import render_state, render_text
from benchmarks.eb_alfred.world import World
from worldmind_local.env import Observation, StepResult, Task, UnknownActionError, lookup_action

__all__ = ["AlfredTwin", "scene_of"]

SUCCESS_FEEDBACK = "Last action executed successfully."
INVALID_PREFIX = "Last action is invalid. "


def scene_of(task: Task) -> Scene:
    """A task's initial scene, from its payload (the task record and its scene facts)."""
    payload = task.payload
    if task.benchmark != "eb_alfred" or not all(k in payload for k in ("key", "record", "facts")):
        raise ValueError(f"task {task.id} is not an EB-ALFRED task (its payload needs key, record and facts)")
    return cached_scene(payload["key"], payload["record"], payload["facts"])


class AlfredTwin:
    """Env for EB-ALFRED on the symbolic twin."""

    benchmark = "eb_alfred"
    max_steps = 30
    max_invalid: int | None = 10

    def __init__(self) -> None:
        self.actions: list[str] = []
        self._scene: Scene | None = None
        self._task: Task | None = None
        self._world: World | None = None
        self._skills: Skills | None = None
        self._handlers: dict[str, Callable[[str], str]] = {}
        self._shared = False
        self.steps = self.invalid = 0
        self.done = False
        self.progress = 0.0
        self.success = False

    # -- episode ---------------------------------------------------------------------------------
    def reset(self, task: Task) -> Observation:
        scene = scene_of(task)
        self._task, self._scene = task, scene
        self.actions = list(scene.actions)
        world = World(scene)
        skills = Skills(world)
        skills.before_write = self._copy_on_write
        self._world, self._skills, self._shared = world, skills, False
        self._handlers = {
            "find": skills.find, "pick": skills.pick, "put": lambda _: skills.put(), "open": skills.open,
            "close": skills.close, "turn_on": skills.turn_on, "turn_off": skills.turn_off,
            "slice": skills.slice, "drop": lambda _: skills.drop(), "unsupported": skills.unsupported,
        }
        self.steps = self.invalid = 0
        self.done = self.success = False
        s, ts = conditions_met(scene.goal, world)
        self.progress = s / ts
        return self._observation()

    def _copy_on_write(self) -> None:
        if self._shared:
            w = self._world
            assert w is not None
            w.parent, w.pos, w.is_open = list(w.parent), list(w.pos), list(w.is_open)
            w.is_on, w.active, w.also_in = list(w.is_on), list(w.active), list(w.also_in)
            self._shared = False

    def _observation(self) -> Observation:
        assert self._world is not None
        snap = self._world.snapshot()
        self._shared = True
        return Observation(partial(render_text, snap), state=partial(render_state, snap))

    def step(self, action_id: int) -> StepResult:
        if self._skills is None or self._scene is None:
            raise RuntimeError("call reset(task) before step()")
        if self.done:
            raise RuntimeError("the episode is over; call reset(task) to start another")
        if not 0 <= action_id < len(self.actions):
            raise UnknownActionError(f"action id {action_id} is outside 0..{len(self.actions) - 1} for task {self._task_id()}")
        skills = self._skills
        verb, arg = self._scene.compiled[action_id]
        if verb != "put" and verb != "open":
            skills.cur_receptacle = None
        skills.changed = False
        msg = self._handlers[verb](arg)
        self.steps += 1
        if msg:
            self.invalid += 1
        if skills.changed:
            s, ts = conditions_met(self._scene.goal, skills.world)
            self.progress, self.success = s / ts, s == ts
        end = None
        if self.success:
            end = "success"
        elif self.invalid >= 10:
            end = "max_invalid"
        elif self.steps >= self.max_steps:
            end = "max_steps"
        self.done = end is not None
        feedback = INVALID_PREFIX + msg if msg else SUCCESS_FEEDBACK
        return StepResult(feedback, self.success, self.progress, bool(msg), self.done, self._observation(), end)

    def action_id(self, name: str) -> int:
        index = self._scene.action_index if self._scene else {}
        return lookup_action(index, name, benchmark=self.benchmark, task=self._task)

    def _task_id(self) -> str:
        return self._task.id if self._task else "(none: reset first)"

    def close(self) -> None:
        self._world = self._skills = None

    def info(self) -> dict[str, Any]:
        """Episode counters (for logs)."""
        return {"steps": self.steps, "invalid": self.invalid, "progress": self.progress, "success": self.success}
