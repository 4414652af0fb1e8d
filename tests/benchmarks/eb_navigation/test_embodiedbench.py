"""The real-simulator wrapper, tested against hand-written recordings of EBNavigationEnv's outputs.

The recordings follow EmbodiedBench's EBNavEnv: reset() returns {'head_rgb': frame}; step() returns
(obs, reward, done, info) with info['env_feedback'] in `Last action {lastAction} ...` form,
info['task_success'] (1.0/0.0), info['last_action_success'], info['distance'], info['env_step'];
AI2-THOR metadata holds the agent pose and objects with a `visible` flag. The blocked-move message is
AI2-THOR 5's (`... is blocking Agent 0 from moving by (x, y, z).`).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.embodiedbench import INSTALL_HINT, EmbodiedBenchNavigation
from worldmind_local.env import Env, Task

BREAD = {"objectId": "Bread|+01.30|+00.98|-01.53", "objectType": "Bread",
         "position": {"x": 1.30, "y": 0.98, "z": -1.53}, "visible": True}  # fmt: skip
FRIDGE = {"objectId": "Fridge|-02.10|+00.00|+01.07", "objectType": "Fridge",
          "position": {"x": -2.10, "y": 0.0, "z": 1.07}, "visible": False}  # fmt: skip


def _meta(x: float, rotation: float = 90.0, horizon: float = 0.0) -> dict[str, Any]:
    return {"agent": {"position": {"x": x, "y": 0.90, "z": -0.9}, "rotation": {"x": 0.0, "y": rotation, "z": 0.0},
                      "cameraHorizon": horizon}, "objects": [BREAD, FRIDGE]}  # fmt: skip


def _info(step: int, feedback: str, success: float, ok: bool, distance: float) -> dict[str, Any]:
    return {"distance": distance, "env_feedback": feedback, "reasoning": "", "instruction": "navigate to the Bread",
            "env_step": step, "episode_elapsed_seconds": 0.5 * step, "task_success": success,
            "last_action_success": ok, "action_id": 0, "action_description": "Move forward by 0.25"}  # fmt: skip


# (expected action, reward, done, info, metadata after the step)
# fmt: off
SUCCESS_EPISODE = [
    (0, 0.0, False, _info(1, "Last action MoveAhead executed successfully.", 0.0, True, 2.62), _meta(-1.25)),
    (0, 0.0, False, _info(2, "Last action MoveAhead is invalid. CounterTop_3f8e is blocking Agent 0 from moving "
                             "by (0.2500, 0.0000, 0.0000).", 0.0, False, 2.62), _meta(-1.25)),
    (7, 0.0, False, _info(3, "Last action LookDown executed successfully.", 0.0, True, 2.62), _meta(-1.25, 90, 30)),
    (2, 1.0, True, _info(4, "Last action MoveRight executed successfully.", 1.0, True, 0.97), _meta(0.9)),
]
# fmt: on


class FakeEBNavigationEnv:
    """Replays a recording through EBNavigationEnv's attributes and methods."""

    instances: list[FakeEBNavigationEnv] = []

    def __init__(self, eval_set: str = "base", **kwargs: Any) -> None:
        self.eval_set, self.kwargs = eval_set, kwargs
        self.dataset: list[dict[str, Any]] = [{"instruction": "EB's own episode 0"}]
        self.number_of_episodes = 60
        self._current_episode_num = 17
        self.recording: list[tuple] = list(SUCCESS_EPISODE)
        self.env = SimpleNamespace(last_event=SimpleNamespace(metadata=_meta(-1.5)))
        self.played: list[dict[str, Any]] = []
        self.actions: list[int] = []
        self.closed = False
        FakeEBNavigationEnv.instances.append(self)

    def reset(self) -> dict[str, Any]:
        self.played.append(self.dataset[self._current_episode_num])
        self._current_episode_num += 1
        self.env.last_event.metadata = _meta(-1.5)
        return {"head_rgb": np.full((500, 500, 3), 90, dtype=np.uint8)}

    def step(self, action: int, reasoning: str, i_flag: int) -> tuple:
        expected, reward, done, info, meta = self.recording.pop(0)
        assert action == expected and reasoning == "" and i_flag == 0
        self.actions.append(action)
        self.env.last_event.metadata = meta
        return {"head_rgb": np.full((500, 500, 3), len(self.actions), dtype=np.uint8)}, reward, done, info

    def close(self) -> None:
        self.closed = True


class NewerSignatureEnv(FakeEBNavigationEnv):
    """EmbodiedBench versions whose step takes (action, reasoning='') only."""

    def step(self, action: int, reasoning: str = "") -> tuple:  # type: ignore[override]
        return super().step(action, reasoning, 0)


def _task() -> Task:
    record = {"targetObjectType": "Bread", "targetObjectIds": BREAD["objectId"],
              "target_position": BREAD["position"], "scene": "FloorPlan11", "object_to_hide": [],
              "agentPose": {"position": {"x": -1.5, "y": 0.9, "z": -0.9}, "rotation": 90.0, "horizon": 0.0},
              "instruction": "navigate to the Bread in the room and be as close as possible to it"}  # fmt: skip
    return Task("eb_navigation/base/0", "eb_navigation", "base", 0, record["instruction"], "kitchen",
                payload={"record": record, "scene": {}})  # fmt: skip


@pytest.mark.parametrize("factory", [FakeEBNavigationEnv, NewerSignatureEnv])
def test_translation_of_a_recorded_episode(factory: type[FakeEBNavigationEnv]) -> None:
    env = ADAPTER.make_env("embodiedbench", env_factory=factory, resolution=500)
    assert isinstance(env, Env) and env.max_steps == 20 and env.max_invalid is None
    task = _task()
    obs = env.reset(task)
    inner = FakeEBNavigationEnv.instances[-1]
    assert inner.eval_set == "base" and inner.kwargs == {"resolution": 500}
    assert inner.played == [task.payload["record"]]  # our episode, not EB's own episode 17
    assert obs.text.splitlines()[1] == "- Bread: about 3.0 m ahead, slightly to the right"
    assert "Fridge" not in obs.text  # THOR says it is not visible
    assert obs.image.size == (500, 500) and obs.image.getpixel((0, 0)) == (90, 90, 90)

    r1 = env.step(0)
    assert r1.feedback == "Last action MoveAhead executed successfully."
    assert (r1.success, r1.invalid, r1.done, r1.progress, r1.end_reason) == (False, False, False, 0.0, None)
    assert r1.info["distance"] == 2.62 and r1.observation.state["position"]["x"] == -1.25

    r2 = env.step(0)
    assert r2.invalid and not r2.done
    assert r2.feedback.endswith(
        "CounterTop_3f8e is blocking Agent 0 from moving by (0.2500, 0.0000, 0.0000)."
    )

    r3 = env.step(7)
    assert "Camera: tilted 30 degrees down." in r3.observation.text

    r4 = env.step(2)
    assert (r4.success, r4.done, r4.progress, r4.end_reason, r4.invalid) == (
        True,
        True,
        1.0,
        "success",
        False,
    )
    assert r4.observation.image.getpixel((0, 0)) == (4, 4, 4)
    assert inner.actions == [0, 0, 7, 2]
    env.close()
    assert inner.closed


def test_step_limit_is_reported() -> None:
    env = EmbodiedBenchNavigation(env_factory=FakeEBNavigationEnv)
    env.reset(_task())
    inner = FakeEBNavigationEnv.instances[-1]
    inner.recording = [(4, 0.0, i == 19, _info(i + 1, "Last action RotateRight executed successfully.", 0.0,
                                               True, 2.8), _meta(-1.5)) for i in range(20)]  # fmt: skip
    results = [env.step(4) for _ in range(20)]
    assert not any(r.done for r in results[:-1])
    assert results[-1].done and results[-1].end_reason == "max_steps" and not results[-1].success


def test_other_suites_play_through_the_base_eval_set() -> None:
    env = EmbodiedBenchNavigation(env_factory=FakeEBNavigationEnv)
    task = _task()
    env.reset(
        Task(task.id, task.benchmark, "generated", 0, task.instruction, task.task_type, payload=task.payload)
    )
    assert FakeEBNavigationEnv.instances[-1].eval_set == "base"


def test_missing_embodiedbench_says_what_to_install() -> None:
    with pytest.raises(ImportError) as err:
        ADAPTER.make_env("embodiedbench")
    assert str(err.value) == INSTALL_HINT
    assert "pip install -e EmbodiedBench" in INSTALL_HINT and "--env twin" in INSTALL_HINT


def test_unknown_env_kind() -> None:
    with pytest.raises(ValueError, match="twin"):
        ADAPTER.make_env("habitat")


def test_wrapper_module_imports_without_embodiedbench() -> None:
    # Importing the module must not need the simulator; only building an env without a factory does.
    import benchmarks.eb_navigation.embodiedbench as mod

    assert Path(mod.__file__).name == "embodiedbench.py"
