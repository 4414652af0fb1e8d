"""A planner that reads only the observation text and feedback reaches the target in >= 90% of episodes."""

from __future__ import annotations

from pathlib import Path

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.greedy import GreedyNavigator, parse_observation, target_type_from_instruction
from worldmind_local.env import Task


def _run(tasks: list[Task]) -> list[str]:
    """The ids of the episodes the greedy planner fails."""
    env = ADAPTER.make_env("twin", images=False)
    failed = []
    for task in tasks:
        obs = env.reset(task)
        target = target_type_from_instruction(task.instruction)
        assert target is not None, task.instruction
        planner, feedback = GreedyNavigator(target), None
        result = None
        for _ in range(20):
            result = env.step(planner.act(obs.text, feedback))
            obs, feedback = result.observation, result.feedback
            if result.done:
                break
        assert result is not None
        if not result.success:
            failed.append(task.id)
    return failed


def test_greedy_text_planner_on_embodiedbench_base(eb_data_dir: Path) -> None:
    tasks = ADAPTER.load_tasks(eb_data_dir, "base")
    failed = _run(tasks)
    assert len(tasks) - len(failed) >= 0.9 * len(tasks), failed


def test_greedy_text_planner_on_generated_base() -> None:
    tasks = ADAPTER.generate_tasks(0, "base", 60)
    failed = _run(tasks)
    assert len(tasks) - len(failed) >= 0.9 * len(tasks), failed


def test_parsing() -> None:
    text = (
        "Objects in view (nearest first):\n"
        "- Cabinet (3 in view, nearest): about 1.0 m ahead, well to the right\n"
        "- Bread: about 2.5 m ahead, slightly to the left\n"
        "- Toaster: about 3.0 m ahead\n"
        "Camera: level."
    )
    assert parse_observation(text) == {"Cabinet": (1.0, 40.0), "Bread": (2.5, -20.0), "Toaster": (3.0, 0.0)}
    assert (
        target_type_from_instruction("navigate to the Pot in the room and be as close as possible to it")
        == "Pot"
    )
    assert target_type_from_instruction("Find the round thing.") is None
