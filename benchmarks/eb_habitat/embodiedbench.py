"""`--env embodiedbench`: EmbodiedBench's real EB-Habitat environment (EBHabEnv) behind our Env contract.

EBHabEnv walks its subset's episodes in order (`reset()` loads the next one; `start_epi_index`
skips ahead at construction), so this wrapper rebuilds it whenever the requested task is not the
next one. Each step's `info` carries what we need: `env_feedback` (the exact feedback string),
`task_success`, `task_progress`, `was_prev_action_invalid`; the observation is the head camera image.
The real simulator exposes no symbolic state, so the observation text says what is known (the last
action, its feedback, whether the robot holds something) unless a `state_abstractor` (e.g. a VLM
summarizer, the paper's M_abs) is given.

Nothing here imports habitat or EmbodiedBench until an environment is actually built. The real
simulator was not run in this project (it needs habitat-sim and an NVIDIA GPU); the translation
layer is tested against hand-written recordings of EBHabEnv's step outputs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from worldmind_local.env import Observation, StepResult, Task, UnknownActionError, lookup_action

from .actions import embedded_skills
from .twin import MAX_INVALID, MAX_STEPS

__all__ = ["EmbodiedBenchHabitatEnv", "INSTALL_HINT", "default_state_text"]

INSTALL_HINT = (
    "--env embodiedbench for eb_habitat needs EmbodiedBench's EB-Habitat stack, which is not installed: "
    "EmbodiedBench itself (git clone https://github.com/EmbodiedBench/EmbodiedBench && pip install -e .), "
    "habitat-sim 0.3.0 from conda (conda install -c conda-forge -c aihabitat habitat-sim=0.3.0 withbullet headless), "
    "habitat-lab 0.3.0, and the ReplicaCAD/YCB assets "
    "(python -m habitat_sim.utils.datasets_download --uids rearrange_task_assets), on Linux with an NVIDIA GPU "
    "(EGL). Without them, use --env twin (the symbolic EB-Habitat twin)."
)

EnvFactory = Callable[..., Any]
StateAbstractor = Callable[[Any, dict[str, Any]], str]


def _import_ebhabenv(**kwargs: Any) -> Any:
    try:
        from embodiedbench.envs.eb_habitat.EBHabEnv import EBHabEnv  # type: ignore[import-not-found]
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return EBHabEnv(**kwargs)


def default_state_text(info: dict[str, Any] | None, holding: bool) -> str:
    """What the wrapper knows without a state abstractor: the last action, its feedback, the hand."""
    hand = "The robot is holding an object." if holding else "The robot is holding nothing."
    if not info:
        return f"The episode has just started (the real simulator reports no symbolic state). {hand}"
    return (
        f"Last action: {info.get('action_description', '?')}. Feedback: {info.get('env_feedback', '')} {hand}"
    )


def _image(obs: Any) -> Any:
    frame = obs.get("head_rgb") if isinstance(obs, dict) else obs
    if frame is None:
        return None
    if hasattr(frame, "cpu"):
        frame = frame.cpu().numpy()
    from PIL import Image

    return Image.fromarray(frame)


class EmbodiedBenchHabitatEnv:
    """Env over EBHabEnv; `env_factory(eval_set=..., start_epi_index=..., ...)` builds the real env."""

    benchmark = "eb_habitat"
    max_steps = MAX_STEPS
    max_invalid: int | None = MAX_INVALID

    def __init__(
        self,
        *,
        env_factory: EnvFactory | None = None,
        resolution: int = 500,
        exp_name: str = "worldmind_local",
        state_abstractor: StateAbstractor | None = None,
    ) -> None:
        self._factory = env_factory or _import_ebhabenv
        self._options = {"resolution": resolution, "exp_name": exp_name}
        self._abstract = state_abstractor
        self._env: Any = None
        self._subset: str | None = None
        self._next_index = -1
        self._task: Task | None = None
        self.actions: list[str] = [s.text for s in embedded_skills()]
        self._ids = {name: i for i, name in enumerate(self.actions)}

    def reset(self, task: Task) -> Observation:
        if self._env is None or self._subset != task.subset or self._next_index != task.index:
            self.close()
            self._env = self._factory(eval_set=task.subset, start_epi_index=task.index, **self._options)
            self._subset = task.subset
            self.actions = list(self._env.language_skill_set)
            self._ids = {name: i for i, name in enumerate(self.actions)}
        obs = self._env.reset()
        self._next_index = task.index + 1
        loaded = getattr(self._env, "episode_language_instruction", task.instruction)
        if loaded != task.instruction:
            raise RuntimeError(
                f"EBHabEnv loaded a different episode for {task.id}: {loaded!r} != {task.instruction!r}"
            )
        self._task, self._steps, self._invalid, self._done = task, 0, 0, False
        return self._observe(obs, None)

    def step(self, action_id: int) -> StepResult:
        if self._env is None or self._done:
            raise RuntimeError("the episode is over (or was never reset); call reset(task) first")
        if not 0 <= action_id < len(self.actions):
            raise UnknownActionError(
                f"action id {action_id} is not one of the {len(self.actions)} EB-Habitat skills"
            )
        obs, _reward, done, info = self._env.step(action_id)
        self._steps += 1
        invalid = bool(info["was_prev_action_invalid"])
        self._invalid += invalid
        success = bool(info["task_success"])
        progress = 1.0 if success else float(info["task_progress"])
        end_reason = self._end_reason(success, bool(done))
        self._done = end_reason is not None
        return StepResult(
            feedback=str(info["env_feedback"]),
            success=success,
            progress=progress,
            invalid=invalid,
            done=self._done,
            observation=self._observe(obs, info),
            end_reason=end_reason,
            info={"action": info.get("action", ""), "num_invalid": self._invalid, "step": self._steps},
        )

    def _end_reason(self, success: bool, done: bool) -> str | None:
        if success:
            return "success"
        if self._invalid >= MAX_INVALID:
            return "max_invalid"
        if self._steps >= MAX_STEPS:
            return "max_steps"
        return "env_done" if done else None

    def _observe(self, obs: Any, info: dict[str, Any] | None) -> Observation:
        image = _image(obs)
        holding = bool(getattr(self._env, "is_holding", False))
        if self._abstract is not None:
            abstract, snapshot = self._abstract, dict(info or {})
            return Observation(lambda: abstract(image, snapshot), image=image)
        return Observation(default_state_text(info, holding), image=image, state={"holding": holding})

    def action_id(self, name: str) -> int:
        return lookup_action(self._ids, name, benchmark=self.benchmark, task=self._task)

    def close(self) -> None:
        if self._env is not None:
            self._env.close()
        self._env, self._subset, self._next_index = None, None, -1
