"""EmbodiedBench's real EB-ALFRED environment (EBAlfEnv on AI2-THOR 2.1.0) behind our Env contract.

Optional: it needs EmbodiedBench installed (its repo, `pip install -e .`), ai2thor 2.1.0 and an X
server; nothing here is imported until the env is made. EBAlfEnv walks its own episode list, so the
wrapper points that list at the one episode asked for (the splits.json entry in the task's payload;
generated tasks have no real scene and are refused). Its step info maps to StepResult field by field:
env_feedback -> feedback, task_success -> success, task_progress -> progress, last_action_success ->
not invalid. The observation carries the camera frame and a text built from AI2-THOR's metadata (what
is visible, held, open, on, sliced), in the same form as the twin's.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

from worldmind_local.env import Observation, StepResult, Task, UnknownActionError, lookup_action

__all__ = ["EmbodiedBenchAlfredEnv", "INSTALL_HINT", "metadata_text"]

INSTALL_HINT = (
    "the embodiedbench env needs EmbodiedBench's EBAlfEnv: clone github.com/EmbodiedBench/EmbodiedBench, "
    "`pip install -e .` in it (it brings ai2thor==2.1.0) and run an X server (see its README); "
    "the symbolic twin (--env twin) needs none of this"
)


def _default_factory(resolution: int) -> Any:
    try:
        from embodiedbench.envs.eb_alfred.EBAlfEnv import EBAlfEnv  # type: ignore[import-not-found]
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return EBAlfEnv(eval_set="base", resolution=resolution)


def metadata_text(metadata: Mapping[str, Any], id_to_name: Mapping[str, str], location: str | None) -> str:
    """The abstract state from AI2-THOR metadata, in the twin's wording."""
    objects = metadata.get("objects", [])
    name = {o["objectId"]: id_to_name.get(o["objectId"], o["objectType"]) for o in objects}
    held = [name.get(o["objectId"], o["objectType"]) for o in metadata.get("inventoryObjects", [])]
    parts = []
    for o in sorted((o for o in objects if o.get("visible")), key=lambda o: name[o["objectId"]]):
        if o["objectId"] in {h.get("objectId") for h in metadata.get("inventoryObjects", [])}:
            continue
        states = []
        if o.get("openable"):
            states.append("open" if o.get("isOpen") else "closed")
        if o.get("toggleable"):
            states.append("on" if o.get("isToggled") else "off")
        if o.get("isSliced"):
            states.append("sliced")
        inside = [name[i] for i in o.get("receptacleObjectIds") or [] if i in name]
        if inside:
            states.append("contains: " + ", ".join(sorted(inside)))
        parts.append(name[o["objectId"]] + (f" ({'; '.join(states)})" if states else ""))
    where = location or "the starting position"
    return f"Location: {where}. Holding: {held[0] if held else 'nothing'}. Visible: {', '.join(parts) or 'nothing of note'}."


def _image(frame: Any) -> Any:
    if frame is None:
        return None
    try:
        from PIL import Image

        return Image.fromarray(frame)
    except (ImportError, TypeError, ValueError):
        return None


class EmbodiedBenchAlfredEnv:
    """Env over EmbodiedBench's EBAlfEnv. `env_factory` makes the EBAlfEnv (tests pass a recorded fake)."""

    benchmark = "eb_alfred"
    max_steps = 30
    max_invalid: int | None = 10

    def __init__(self, *, env_factory: Callable[[int], Any] | None = None, resolution: int = 500) -> None:
        self._factory = env_factory or _default_factory
        self._resolution = resolution
        self._env: Any = None
        self._task: Task | None = None
        self.actions: list[str] = []
        self._index: dict[str, int] = {}
        self.steps = self.invalid = 0

    def _eb(self) -> Any:
        if self._env is None:
            self._env = self._factory(self._resolution)
        return self._env

    def reset(self, task: Task) -> Observation:
        entry = task.payload.get("split")
        if not entry:
            raise ValueError(f"task {task.id} is not an EmbodiedBench episode (generated tasks run on the twin only)")
        env = self._eb()
        env.dataset, env.number_of_episodes, env._current_episode_num = [dict(entry)], 1, 0
        obs = env.reset()
        self._task = task
        self.actions = list(env.language_skill_set)
        self._index = {a: k for k, a in enumerate(self.actions)}
        self.steps = self.invalid = 0
        return self._observation(obs)

    def _observation(self, obs: Mapping[str, Any]) -> Observation:
        env = self._env
        thor = getattr(env, "env", None)
        metadata = getattr(getattr(thor, "last_event", None), "metadata", None) or {}
        id_to_name = dict(getattr(env, "id_to_name_dict", None) or {})
        location = getattr(thor, "cur_receptacle", None)
        snapshot = {"metadata": metadata, "location": location}
        return Observation(
            partial(metadata_text, metadata, id_to_name, location),
            state=lambda: {"location": snapshot["location"], "n_objects": len(metadata.get("objects", []))},
            image=_image(obs.get("head_rgb")),
        )

    def step(self, action_id: int) -> StepResult:
        if self._task is None:
            raise RuntimeError("call reset(task) before step()")
        if not 0 <= action_id < len(self.actions):
            raise UnknownActionError(f"action id {action_id} is outside 0..{len(self.actions) - 1} for task {self._task.id}")
        obs, _reward, done, info = self._env.step(action_id)
        self.steps += 1
        invalid = not bool(info.get("last_action_success", 0.0))
        self.invalid += int(invalid)
        success = bool(info.get("task_success", 0.0))
        end = None
        if success:
            end = "success"
        elif self.invalid >= 10:
            end = "max_invalid"
        elif self.steps >= self.max_steps:
            end = "max_steps"
        elif done:
            end = "done"
        return StepResult(
            feedback=str(info.get("env_feedback", "")), success=success, progress=float(info.get("task_progress", 0.0)),
            invalid=invalid, done=bool(done) or end is not None, observation=self._observation(obs), end_reason=end,
            info={k: info[k] for k in ("object_states", "env_step") if k in info},
        )

    def action_id(self, name: str) -> int:
        return lookup_action(self._index, name, benchmark=self.benchmark, task=self._task)

    def close(self) -> None:
        if self._env is not None and hasattr(self._env, "close"):
            self._env.close()
        self._env = None
