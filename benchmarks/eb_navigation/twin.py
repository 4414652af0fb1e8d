"""The EB-Navigation twin: EmbodiedBench's interface over a 2-D room model.

Faithful to EBNavEnv: the 8 actions in id order, 0.25 m moves relative to the heading, 90-degree
turns, camera tilt in 30-degree steps within AI2-THOR's horizon limits (30 degrees up, 60 down; a tilt
past them fails with THOR's message, as in THOR, rather than being clamped silently), success when
the xz distance to `target_position` is at most 1.0 m (checked after every action; the episode ends
on success), at most 20 steps, no invalid-action limit, feedback
`Last action {THOR action} executed successfully.` / `Last action {THOR action} is invalid. {error}`.
A blocked move gives AI2-THOR 5's collision message,
`{blocker} is blocking Agent 0 from moving by ({dx:.4f}, 0.0000, {dz:.4f}).` (dx, dz = the world offset
of the attempted move), and leaves the pose unchanged; the blocker is `Wall` or the obstacle's object
type, where THOR names the Unity object it hit. An action id outside 0-7 issues THOR's `Done`, which
ends the episode (the data sheet's account of EBNavEnv).

What is approximated: the room (geometry.py, scenes.py), object visibility (no occlusion; observe.py).
The step hot path touches only integers and a set; observation text and image are built lazily from an
immutable snapshot when read.
"""

from __future__ import annotations

import math
from functools import partial
from typing import TYPE_CHECKING, Any

from benchmarks.eb_navigation.actions import (
    ACTION_TEXTS,
    ACTIONS,
    LOOK_DOWN,
    LOOK_UP,
    ROTATE_LEFT,
    ROTATE_RIGHT,
)
from benchmarks.eb_navigation.expert import heading_index, move_delta
from benchmarks.eb_navigation.geometry import (
    MOVE_STEP,
    SUCCESS_DISTANCE,
    WALL_NAME,
    Floor,
    Scene,
    compile_floor,
)
from benchmarks.eb_navigation.observe import ObjectTuple, Pose, describe, visible_objects
from benchmarks.eb_navigation.render import IMAGE_SIZE, render_top_down
from worldmind_local.env import Observation, StepResult, Task, lookup_action

if TYPE_CHECKING:
    from collections.abc import Callable

    from PIL.Image import Image

__all__ = ["NavigationTwin", "NavObservation", "MAX_STEPS", "HORIZON_LIMITS"]

MAX_STEPS = 20
HORIZON_LIMITS = (-30.0, 60.0)  # THOR: maxUpwardLookAngle 30, maxDownwardLookAngle 60 (horizon > 0 = down)
_OK = tuple(f"Last action {a.thor_action} executed successfully." for a in ACTIONS)
_DONE_FEEDBACK = "Last action Done executed successfully."
_LOOK_ERRORS = {
    LOOK_UP: "can't look up beyond 30 degrees above the forward horizon",
    LOOK_DOWN: "can't look down beyond 60 degrees below the forward horizon",
}
_DELTAS = tuple(tuple(move_delta(a, h) for a in range(4)) for h in range(4))


class NavObservation(Observation):
    """An Observation whose image is rendered only when read (the top-down picture costs 2-3 ms, the
    step hot path budget is 50 us). Setting `image` replaces the lazy picture."""

    __slots__ = ("_image", "_image_fn")
    _image: Image | None
    _image_fn: Callable[[], Image | None] | None

    def __init__(
        self,
        text: str | Callable[[], str],
        *,
        state: dict[str, Any] | Callable[[], dict[str, Any]],
        image_fn: Callable[[], Image | None] | None = None,
    ) -> None:
        super().__init__(text, state=state)
        self._image_fn = image_fn

    @property  # type: ignore[override]
    def image(self) -> Image | None:
        if self._image is None and self._image_fn is not None:
            self._image, self._image_fn = self._image_fn(), None
        return self._image

    @image.setter
    def image(self, value: Image | None) -> None:
        self._image, self._image_fn = value, None


def _fmt4(v: float) -> str:
    s = f"{v:.4f}"
    return "0.0000" if s == "-0.0000" else s


def _text(
    scene: Scene, floor: Floor, cell: tuple[int, int, int], pose: Pose, objects: tuple[ObjectTuple, ...]
) -> str:
    i, j, h = cell
    di, dj = _DELTAS[h][0]
    blocked = None
    if (i + di, j + dj) not in floor.free:
        blocked = scene.blocker(*floor.position(i + di, j + dj)) or WALL_NAME
    return describe(visible_objects(pose, objects), pose.horizon, blocked)


def _image(scene: Scene, pose: Pose, objects: tuple[ObjectTuple, ...], size: int) -> Image:
    return render_top_down(scene, pose, visible_objects(pose, objects), size)


class NavigationTwin:
    """Env for EB-Navigation tasks (EmbodiedBench's or generated); see the module docstring."""

    benchmark = "eb_navigation"
    max_steps = MAX_STEPS
    max_invalid: int | None = None

    def __init__(self, *, images: bool = True, image_size: int = IMAGE_SIZE) -> None:
        self.actions: list[str] = list(ACTION_TEXTS)
        self._ids = {name: i for i, name in enumerate(self.actions)}
        self._images = images
        self._image_size = image_size
        self._task: Task | None = None
        self._done = True

    def reset(self, task: Task) -> Observation:
        record = task.payload["record"]
        self._task = task
        self._scene = Scene.from_dict(task.payload["scene"])
        self._objects = tuple((o.id, o.type, o.x, o.y, o.z) for o in self._scene.objects)
        pose = record["agentPose"]
        self._x0, self._y, self._z0 = (float(pose["position"][k]) for k in ("x", "y", "z"))
        self._floor = compile_floor(self._scene, self._x0, self._z0)
        self._target = (float(record["target_position"]["x"]), float(record["target_position"]["z"]))
        self._i = self._j = 0
        self._h = heading_index(float(pose["rotation"]))
        self._horizon = float(pose["horizon"])
        self._steps = 0
        self._done = False
        return self._observe()

    def step(self, action_id: int) -> StepResult:
        if self._task is None:
            raise RuntimeError("call reset(task) before step()")
        if self._done:
            raise RuntimeError(f"episode {self._task.id} is over; call reset(task) to start another")
        self._steps += 1
        invalid, done_action = False, False
        if 0 <= action_id < 4:
            di, dj = _DELTAS[self._h][action_id]
            if (self._i + di, self._j + dj) in self._floor.free:
                self._i += di
                self._j += dj
                feedback = _OK[action_id]
            else:
                invalid, feedback = True, self._blocked_feedback(action_id, di, dj)
        elif action_id == ROTATE_RIGHT or action_id == ROTATE_LEFT:
            self._h = (self._h + (1 if action_id == ROTATE_RIGHT else 3)) % 4
            feedback = _OK[action_id]
        elif action_id == LOOK_UP or action_id == LOOK_DOWN:
            horizon = self._horizon + (30.0 if action_id == LOOK_DOWN else -30.0)
            if HORIZON_LIMITS[0] <= horizon <= HORIZON_LIMITS[1]:
                self._horizon = horizon
                feedback = _OK[action_id]
            else:
                invalid = True
                feedback = (
                    f"Last action {ACTIONS[action_id].thor_action} is invalid. {_LOOK_ERRORS[action_id]}"
                )
        else:
            done_action, feedback = True, _DONE_FEEDBACK
        x, z = self._x0 + MOVE_STEP * self._i, self._z0 + MOVE_STEP * self._j
        distance = math.sqrt((x - self._target[0]) ** 2 + (z - self._target[1]) ** 2)
        success = distance <= SUCCESS_DISTANCE
        end_reason = None
        if success:
            end_reason = "success"
        elif self._steps >= MAX_STEPS:
            end_reason = "max_steps"
        elif done_action:
            end_reason = "done_action"
        self._done = end_reason is not None
        return StepResult(
            feedback,
            success,
            1.0 if success else 0.0,
            invalid,
            self._done,
            self._observe(),
            end_reason,
            {"distance": distance, "last_action_success": not invalid},
        )

    def _blocked_feedback(self, action_id: int, di: int, dj: int) -> str:
        nx, nz = self._floor.position(self._i + di, self._j + dj)
        blocker = self._scene.blocker(nx, nz) or WALL_NAME
        offset = f"({_fmt4(di * MOVE_STEP)}, 0.0000, {_fmt4(dj * MOVE_STEP)})"
        return (
            f"Last action {ACTIONS[action_id].thor_action} is invalid. "
            f"{blocker} is blocking Agent 0 from moving by {offset}."
        )

    def _pose(self) -> Pose:
        x, z = self._floor.position(self._i, self._j)
        return Pose(x, self._y, z, 90.0 * self._h, self._horizon)

    def _observe(self) -> NavObservation:
        pose = self._pose()
        cell = (self._i, self._j, self._h)
        text_fn = partial(_text, self._scene, self._floor, cell, pose, self._objects)
        state_fn = partial(_state, self._scene.name, pose, cell, self._steps, self._target)
        image_fn = (
            partial(_image, self._scene, pose, self._objects, self._image_size) if self._images else None
        )
        return NavObservation(text_fn, state=state_fn, image_fn=image_fn)

    def render(self) -> Image:
        """The top-down picture of the current pose (also what `Observation.image` gives)."""
        if self._task is None:
            raise RuntimeError("call reset(task) before render()")
        return _image(self._scene, self._pose(), self._objects, self._image_size)

    def action_id(self, name: str) -> int:
        return lookup_action(self._ids, name, benchmark=self.benchmark, task=self._task)

    def close(self) -> None:
        self._task = None
        self._done = True


def _state(
    scene: str, pose: Pose, cell: tuple[int, int, int], steps: int, target: tuple[float, float]
) -> dict[str, Any]:
    return {
        "scene": scene,
        "position": {"x": round(pose.x, 4), "y": round(pose.y, 4), "z": round(pose.z, 4)},
        "rotation": pose.rotation,
        "horizon": pose.horizon,
        "cell": list(cell[:2]),
        "steps": steps,
        "distance_to_target": round(math.hypot(pose.x - target[0], pose.z - target[1]), 4),
    }
