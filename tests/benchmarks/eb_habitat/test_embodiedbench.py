"""The EBHabEnv wrapper, driven by a stand-in that replays hand-written EBHabEnv step outputs."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from benchmarks.eb_habitat import ADAPTER
from benchmarks.eb_habitat.actions import embedded_skills
from benchmarks.eb_habitat.embodiedbench import INSTALL_HINT, EmbodiedBenchHabitatEnv
from worldmind_local.env import Env, Task, UnknownActionError

RECORDING = json.loads((Path(__file__).parent / "data" / "ebhabenv_recording.json").read_text())["episodes"]


class RecordedEBHabEnv:
    """Mimics EBHabEnv's surface: episodes in order from start_epi_index, (obs, reward, done, info) steps."""

    built: list[tuple[str, int]] = []

    def __init__(
        self, eval_set: str, start_epi_index: int = 0, resolution: int = 500, exp_name: str = ""
    ) -> None:
        self.eval_set, self.next_episode = eval_set, start_epi_index
        self.language_skill_set = [s.text for s in embedded_skills()]
        self.is_holding = False
        self.closed = False
        RecordedEBHabEnv.built.append((eval_set, start_epi_index))

    def _obs(self) -> dict[str, Any]:
        return {"head_rgb": np.zeros((4, 4, 3), dtype=np.uint8)}

    def reset(self) -> dict[str, Any]:
        record = RECORDING[f"{self.eval_set}/{self.next_episode}"]
        self.episode_language_instruction = record["instruction"]
        if "repeat" in record:
            steps = [
                dict(record["repeat_step"], done=i + 1 >= record["repeat"]) for i in range(record["repeat"])
            ]
        else:
            steps = record["steps"]
        self.steps = iter(steps)
        self.next_episode += 1
        return self._obs()

    def step(self, action: int) -> tuple[dict[str, Any], float, bool, dict[str, Any]]:
        step = next(self.steps)
        assert step["action_id"] == action, "the test drives the recorded actions"
        info = dict(step["info"])
        feedback = info["env_feedback"]
        if not info["was_prev_action_invalid"]:
            self.is_holding = "holding nothing" not in feedback and ("holding" in feedback or self.is_holding)
        return self._obs(), 0.0, step["done"], info

    def close(self) -> None:
        self.closed = True


def task(subset: str, index: int) -> Task:
    record = RECORDING[f"{subset}/{index}"]
    return Task(f"eb_habitat/{subset}/{index}", "eb_habitat", subset, index, record["instruction"], "")


@pytest.fixture
def env() -> EmbodiedBenchHabitatEnv:
    RecordedEBHabEnv.built = []
    return EmbodiedBenchHabitatEnv(env_factory=RecordedEBHabEnv)


def test_translates_a_successful_episode(env):
    obs = env.reset(task("base", 0))
    assert isinstance(env, Env) and len(env.actions) == 70
    assert obs.image.size == (4, 4) and "just started" in obs.text
    results = [env.step(i) for i in (7, 16, 47, 10, 54)]
    assert [r.invalid for r in results] == [False, True, False, False, False]
    assert [r.progress for r in results] == [0.25, 0.25, 0.5, 0.75, 1.0]
    assert results[2].feedback == "Last action executed successfully and you are holding toy airplane."
    assert "holding an object" in results[2].observation.text
    assert results[-1].success and results[-1].done and results[-1].end_reason == "success"
    assert results[1].info["action"] == "pick_ball(robot_0)"
    with pytest.raises(RuntimeError):
        env.step(0)


def test_sequential_tasks_reuse_the_env_and_jumps_rebuild_it(env):
    env.reset(task("base", 0))
    env.reset(task("base", 1))  # next episode: same EBHabEnv
    assert env.step(56).feedback.startswith("Last action is invalid. Robot cannot place")
    env.reset(task("base", 17))  # a jump: rebuilt with start_epi_index
    assert RecordedEBHabEnv.built == [("base", 0), ("base", 17)]
    closing = [env.step(i) for i in (4, 61)][-1]
    assert closing.feedback == "Last action executed successfully and now refrigerator is closed."
    assert closing.end_reason == "success"


def test_ten_invalid_actions_end_with_max_invalid(env):
    env.reset(task("long_horizon", 0))
    results = [env.step(62) for _ in range(10)]
    assert [r.done for r in results] == [False] * 9 + [True]
    assert results[-1].end_reason == "max_invalid" and results[-1].progress == 0.0


def test_a_different_loaded_episode_is_an_error(env):
    wrong = Task("eb_habitat/base/0", "eb_habitat", "base", 0, "Some other instruction", "")
    with pytest.raises(RuntimeError, match="different episode"):
        env.reset(wrong)


def test_state_abstractor_and_action_lookup():
    seen: list[dict] = []

    def abstractor(image: Any, info: dict) -> str:
        seen.append(info)
        return f"image {image.size}"

    env = EmbodiedBenchHabitatEnv(env_factory=RecordedEBHabEnv, state_abstractor=abstractor)
    env.reset(task("base", 0))
    result = env.step(env.action_id("navigate to the table 2"))
    assert result.observation.text == "image (4, 4)" and seen[-1]["env_step"] == 1
    with pytest.raises(UnknownActionError, match="eb_habitat/base/0"):
        env.action_id("jump")


def test_missing_embodiedbench_gives_the_install_hint():
    env = ADAPTER.make_env("embodiedbench")  # building the wrapper imports nothing heavy
    with pytest.raises(ImportError) as info:
        env.reset(task("base", 0))
    assert str(info.value) == INSTALL_HINT and "habitat-sim" in INSTALL_HINT and "--env twin" in INSTALL_HINT
