"""A hand-built EB-Navigation task in a 4 m x 4 m room, for twin tests that need exact geometry."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from benchmarks.eb_navigation.geometry import Scene, SceneObject
from worldmind_local.env import Task


def _task(x: float = 0.5, z: float = 0.5, rotation: float = 0.0, horizon: float = 0.0) -> Task:
    bread = SceneObject("Bread|+03.00|+00.90|+03.50", "Bread", 3.0, 0.9, 3.5, (0.3, 0.3))
    can = SceneObject("GarbageCan|+00.50|+00.00|+02.00", "GarbageCan", 0.5, 0.0, 2.0, (0.2, 0.2))
    scene = Scene("TestRoom", (0.0, 0.0, 4.0, 4.0), (bread, can), "test")
    record: dict[str, Any] = {
        "targetObjectType": "Bread",
        "targetObjectIds": bread.id,
        "target_position": {"x": 3.0, "y": 0.9, "z": 3.5},
        "agentPose": {"position": {"x": x, "y": 0.9, "z": z}, "rotation": rotation, "horizon": horizon},
        "scene": "TestRoom",
        "object_to_hide": [],
        "instruction": "navigate to the Bread in the room and be as close as possible to it",
    }
    return Task("eb_navigation/test/0", "eb_navigation", "base", 0, record["instruction"], "kitchen",
                payload={"record": record, "scene": scene.to_dict()})  # fmt: skip


@pytest.fixture
def make_task() -> Callable[..., Task]:
    """make_task(x=0.5, z=0.5, rotation=0.0, horizon=0.0): the agent at (x, z); Bread at (3.0, 3.5) on a
    0.6 m counter proxy; a garbage can at (0.5, 2.0); walls at x, z = 0 and 4."""
    return _task
