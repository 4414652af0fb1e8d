"""`--env embodiedbench`: EmbodiedBench's real EBNavigationEnv (AI2-THOR 5.0) behind our Env contract.

Needs EmbodiedBench installed (its `embodiedbench` package) with `ai2thor==5.0.0` and a machine where
AI2-THOR's CloudRendering runs (Vulkan on a GPU). None of that exists on this project's machines, so
this wrapper was written against EBNavEnv's interface and tested only against hand-written recordings
of its outputs; the real simulator was not run here.

Translation: EBNavigationEnv.reset() takes no task (it plays its own dataset in order), so the wrapper
points its dataset at the one record to play (`dataset`, `number_of_episodes`, `_current_episode_num`,
the attributes EBNavEnv reads) and calls reset(). step(action_id) passes the id through (EBNavEnv
itself handles ids outside 0-7) and maps its info: `env_feedback` -> feedback (EmbodiedBench's exact
string), `task_success` -> success (and progress, which EB-Navigation does not report separately),
`last_action_success` -> invalid, `done` -> done. The image is `head_rgb`, converted to PIL only when
read. The observation text is built from AI2-THOR's metadata (objects THOR marks visible, the agent's
pose) with the same formatter as the twin, so planners read the same kind of text on both.
"""

from __future__ import annotations

import inspect
from functools import partial
from typing import TYPE_CHECKING, Any

from benchmarks.eb_navigation.actions import ACTION_TEXTS
from benchmarks.eb_navigation.observe import ObjectTuple, Pose, describe, visible_objects
from benchmarks.eb_navigation.twin import MAX_STEPS, NavObservation
from worldmind_local.env import Observation, StepResult, Task, lookup_action

if TYPE_CHECKING:
    from collections.abc import Callable

    from PIL.Image import Image

__all__ = ["EmbodiedBenchNavigation", "INSTALL_HINT", "VALID_EVAL_SETS"]

VALID_EVAL_SETS = ("base", "common_sense", "complex_instruction", "visual_appearance", "long_horizon")
INSTALL_HINT = (
    "the 'embodiedbench' env of eb_navigation needs EmbodiedBench's EBNavigationEnv: "
    "`git clone https://github.com/EmbodiedBench/EmbodiedBench && pip install -e EmbodiedBench "
    "ai2thor==5.0.0`, on a machine where AI2-THOR CloudRendering runs (Vulkan GPU). "
    "Use `--env twin` to run the symbolic twin instead."
)


def _load_env_class() -> Callable[..., Any]:
    try:
        from embodiedbench.envs.eb_navigation.EBNavEnv import EBNavigationEnv  # type: ignore[import-not-found]
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return EBNavigationEnv


def _snapshot(metadata: dict[str, Any]) -> tuple[Pose, tuple[ObjectTuple, ...]]:
    """The agent pose and the objects THOR marks visible, copied out of one event's metadata."""
    agent = metadata.get("agent", {})
    pos = agent.get("position", {})
    rot = agent.get("rotation", {})
    pose = Pose(
        float(pos.get("x", 0.0)),
        float(pos.get("y", 0.0)),
        float(pos.get("z", 0.0)),
        float(rot.get("y", 0.0) if isinstance(rot, dict) else rot),
        float(agent.get("cameraHorizon", 0.0)),
    )
    objects = tuple(
        (
            o["objectId"],
            o["objectType"],
            float(o["position"]["x"]),
            float(o["position"]["y"]),
            float(o["position"]["z"]),
        )
        for o in metadata.get("objects", [])
        if o.get("visible")
    )
    return pose, objects


def _text(pose: Pose, objects: tuple[ObjectTuple, ...]) -> str:
    return describe(visible_objects(pose, objects), pose.horizon)


def _to_pil(frame: Any) -> Image | None:
    if frame is None:
        return None
    from PIL import Image as PILImage

    return PILImage.fromarray(frame)


class EmbodiedBenchNavigation:
    """Env over a real EBNavigationEnv. Options: `env_factory` (a callable building the EB env; default
    EmbodiedBench's class), and keyword arguments passed to it (e.g. resolution=500, exp_name=...)."""

    benchmark = "eb_navigation"
    max_steps = MAX_STEPS
    max_invalid: int | None = None

    def __init__(self, *, env_factory: Callable[..., Any] | None = None, **env_kwargs: Any) -> None:
        self.actions: list[str] = list(ACTION_TEXTS)
        self._factory = env_factory if env_factory is not None else _load_env_class()
        self._env_kwargs = env_kwargs
        self._inner: Any = None
        self._task: Task | None = None
        self._steps = 0

    def _env_for(self, subset: str) -> Any:
        if self._inner is None:
            eval_set = subset if subset in VALID_EVAL_SETS else "base"
            self._inner = self._factory(eval_set=eval_set, **self._env_kwargs)
        return self._inner

    def reset(self, task: Task) -> Observation:
        inner = self._env_for(task.subset)
        inner.dataset = [task.payload["record"]]
        inner.number_of_episodes = 1
        inner._current_episode_num = 0
        obs = inner.reset()
        self._task, self._steps = task, 0
        return self._observation(obs)

    def _call_step(self, action_id: int) -> tuple[Any, Any, Any, dict[str, Any]]:
        step = self._inner.step
        params = inspect.signature(step).parameters
        kwargs: dict[str, Any] = {}
        if "reasoning" in params:
            kwargs["reasoning"] = ""
        if "i_flag" in params:  # some EmbodiedBench versions log per step with this flag
            kwargs["i_flag"] = 0
        return step(action_id, **kwargs)

    def step(self, action_id: int) -> StepResult:
        if self._task is None:
            raise RuntimeError("call reset(task) before step()")
        obs, reward, done, info = self._call_step(action_id)
        self._steps += 1
        success = bool(info.get("task_success", reward))
        invalid = not bool(info.get("last_action_success", True))
        done = bool(done) or success
        end_reason = None
        if success:
            end_reason = "success"
        elif done:
            end_reason = "max_steps" if self._steps >= MAX_STEPS else "done_action"
        keep = ("distance", "env_step", "last_action_success", "action_id")
        return StepResult(
            feedback=str(info["env_feedback"]),
            success=success,
            progress=1.0 if success else 0.0,
            invalid=invalid,
            done=done,
            observation=self._observation(obs),
            end_reason=end_reason,
            info={k: info[k] for k in keep if k in info},
        )

    def _observation(self, obs: Any) -> Observation:
        event = getattr(getattr(self._inner, "env", None), "last_event", None)
        pose, objects = _snapshot(getattr(event, "metadata", {}) or {})
        frame = obs.get("head_rgb") if isinstance(obs, dict) else None
        state = {"position": {"x": pose.x, "y": pose.y, "z": pose.z}, "rotation": pose.rotation,
                 "horizon": pose.horizon, "steps": self._steps}  # fmt: skip
        return NavObservation(partial(_text, pose, objects), state=state, image_fn=partial(_to_pil, frame))

    def action_id(self, name: str) -> int:
        ids = {action: i for i, action in enumerate(self.actions)}
        return lookup_action(ids, name, benchmark=self.benchmark, task=self._task)

    def close(self) -> None:
        if self._inner is not None:
            self._inner.close()
            self._inner = None
