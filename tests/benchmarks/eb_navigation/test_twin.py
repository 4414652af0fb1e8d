"""The EB-Navigation twin: EmbodiedBench's feedback, limits and success, on a hand-built room and the data."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.actions import (
    ACTION_TEXTS,
    LOOK_DOWN,
    LOOK_UP,
    MOVE_AHEAD,
    MOVE_BACK,
    MOVE_LEFT,
    MOVE_RIGHT,
    ROTATE_LEFT,
    ROTATE_RIGHT,
)
from benchmarks.eb_navigation.twin import NavigationTwin
from worldmind_local.env import Env, Task, UnknownActionError

MakeTask = Callable[..., Task]


def _pos(result_or_obs) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    obs = getattr(result_or_obs, "observation", result_or_obs)
    return obs.state["position"]["x"], obs.state["position"]["z"]


def test_env_contract(make_task: MakeTask) -> None:
    env = NavigationTwin()
    assert isinstance(env, Env)
    assert env.actions == list(ACTION_TEXTS) and env.max_steps == 20 and env.max_invalid is None
    obs = env.reset(make_task())
    assert obs.text == (
        "Objects in view (nearest first):\n"
        "- GarbageCan: about 1.5 m ahead\n"
        "- Bread: about 4.0 m ahead, well to the right\n"
        "Camera: level."
    )
    assert obs.state["steps"] == 0 and obs.state["rotation"] == 0.0


@pytest.mark.parametrize(
    ("action", "thor"),
    [(MOVE_AHEAD, "MoveAhead"), (MOVE_RIGHT, "MoveRight"), (ROTATE_RIGHT, "RotateRight"),
     (ROTATE_LEFT, "RotateLeft"), (LOOK_UP, "LookUp"), (LOOK_DOWN, "LookDown")],
)  # fmt: skip
def test_valid_feedback_names_the_thor_action(make_task: MakeTask, action: int, thor: str) -> None:
    env = NavigationTwin()
    env.reset(make_task(x=1.5, z=1.0))
    r = env.step(action)
    assert r.feedback == f"Last action {thor} executed successfully."
    assert not r.invalid and not r.done and r.progress == 0.0 and r.end_reason is None


def test_move_into_a_wall_is_invalid_and_leaves_the_pose(make_task: MakeTask) -> None:
    env = NavigationTwin()
    start = env.reset(make_task(x=0.25, z=1.0, rotation=270.0))  # facing -x, 0.25 m from the wall x = 0
    r = env.step(MOVE_AHEAD)
    assert r.feedback == (
        "Last action MoveAhead is invalid. Wall is blocking Agent 0 from moving by (-0.2500, 0.0000, 0.0000)."
    )
    assert r.invalid and not r.done and not r.success
    assert _pos(r) == _pos(start) == (0.25, 1.0) and r.observation.state["rotation"] == 270.0
    assert r.info["last_action_success"] is False
    assert "Right in front (within 0.25 m): Wall; moving forward is blocked." in r.observation.text


def test_move_into_an_obstacle_names_it(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task(x=0.5, z=1.5, rotation=0.0))  # the garbage can is 0.5 m ahead
    r = env.step(MOVE_AHEAD)
    assert r.feedback.startswith(
        "Last action MoveAhead is invalid. GarbageCan is blocking Agent 0 from moving by"
    )
    assert r.feedback.endswith("(0.0000, 0.0000, 0.2500).") and _pos(r) == (0.5, 1.5)
    r = env.step(MOVE_BACK)
    assert not r.invalid and _pos(r) == (0.5, 1.25)


def test_moves_are_relative_to_the_heading(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task(x=2.0, z=2.0, rotation=90.0))  # facing +x: right is -z
    assert _pos(env.step(MOVE_AHEAD)) == (2.25, 2.0)
    assert _pos(env.step(MOVE_RIGHT)) == (2.25, 1.75)
    assert _pos(env.step(MOVE_LEFT)) == (2.25, 2.0)
    assert _pos(env.step(MOVE_BACK)) == (2.0, 2.0)
    r = env.step(ROTATE_RIGHT)
    assert r.observation.state["rotation"] == 180.0 and _pos(r) == (2.0, 2.0)
    assert _pos(env.step(MOVE_AHEAD)) == (2.0, 1.75)


def test_camera_tilt_follows_thor_horizon_limits(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task())
    assert not env.step(LOOK_UP).invalid
    r = env.step(LOOK_UP)
    assert r.invalid
    assert (
        r.feedback
        == "Last action LookUp is invalid. can't look up beyond 30 degrees above the forward horizon"
    )
    assert r.observation.state["horizon"] == -30.0 and "Camera: tilted 30 degrees up." in r.observation.text
    for _ in range(3):
        assert not env.step(LOOK_DOWN).invalid
    r = env.step(LOOK_DOWN)
    assert r.feedback == (
        "Last action LookDown is invalid. can't look down beyond 60 degrees below the forward horizon"
    )
    assert r.observation.state["horizon"] == 60.0


def test_success_within_one_metre_ends_the_episode(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task(x=3.0, z=2.25, rotation=0.0))  # 1.25 m from the bread
    r = env.step(ROTATE_RIGHT)
    assert not r.success and not r.done
    r = env.step(MOVE_LEFT)  # to z = 2.5: exactly 1.0 m away
    assert r.success and r.done and r.progress == 1.0 and r.end_reason == "success"
    assert r.info["distance"] == pytest.approx(1.0)
    with pytest.raises(RuntimeError, match="over"):
        env.step(MOVE_AHEAD)


def test_twenty_steps_and_no_invalid_limit(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task(x=0.25, z=1.0, rotation=270.0))
    results = [env.step(MOVE_AHEAD) for _ in range(20)]  # every one blocked by the wall
    assert all(r.invalid for r in results)
    assert not any(r.done for r in results[:-1])
    assert results[-1].done and results[-1].end_reason == "max_steps" and not results[-1].success


def test_action_id_outside_the_space_issues_done(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task())
    r = env.step(8)
    assert r.feedback == "Last action Done executed successfully."
    assert r.done and r.end_reason == "done_action" and not r.success


def test_action_names(make_task: MakeTask) -> None:
    env = NavigationTwin()
    env.reset(make_task())
    assert env.action_id("Tilt the camera upward by 30 degrees.") == LOOK_UP
    with pytest.raises(UnknownActionError, match="eb_navigation/test/0"):
        env.action_id("Jump")


def test_observation_is_bound_to_its_step(make_task: MakeTask) -> None:
    env = NavigationTwin()
    first = env.reset(make_task())
    env.step(ROTATE_RIGHT)
    env.step(MOVE_AHEAD)
    fresh = NavigationTwin().reset(make_task())
    assert first.text == fresh.text and first.state == fresh.state  # read late, still the reset's view


def test_image_is_lazy_and_optional(make_task: MakeTask) -> None:
    env = NavigationTwin()
    obs = env.reset(make_task())
    assert obs._image is None  # nothing rendered yet
    img = obs.image
    assert img is not None and img.size == (448, 448) and img.mode == "RGB"
    assert obs.image is img
    assert env.render().size == (448, 448)
    assert NavigationTwin(images=False).reset(make_task()).image is None
    assert NavigationTwin(image_size=224).reset(make_task()).image.size == (224, 224)


def test_step_before_reset_fails() -> None:
    with pytest.raises(RuntimeError, match="reset"):
        NavigationTwin().step(0)


def test_expert_plans_of_every_episode_succeed(eb_data_dir: Path) -> None:
    env = ADAPTER.make_env("twin", images=False)
    for subset in ADAPTER.subsets:
        for task in ADAPTER.load_tasks(eb_data_dir, subset):
            env.reset(task)
            assert task.expert_plan
            results = [env.step(env.action_id(a)) for a in task.expert_plan]
            assert results[-1].success and results[-1].end_reason == "success", task.id
            assert not any(r.done for r in results[:-1]) and not any(r.invalid for r in results), task.id
