"""A small hand-written kitchen in the data pack's format, so twin tests need no data pack.

Layout (x, z in metres; stations far apart so each is seen alone):
  counter (0, 0): CounterTop, Cabinet, Apple, Knife      fridge (3, 0): Fridge (holds a Mug)
  sink (3, 3): SinkBasin, Sink, Faucet                    microwave (0, 3): Microwave
  table (-3, 3): DiningTable, Apple_2, Potato             far cabinet (-3, 0): Cabinet_2
  lamp desk (6, 3): Desk, DeskLamp, Book                  agent starts at (6, 6)
"""

from __future__ import annotations

from typing import Any

import pytest

from worldmind_local.env import Task

RECEPTACLES = {
    "CounterTop|+00.00|+00.95|+00.00": ("CounterTop", False),
    "Cabinet|+00.40|+00.40|+00.00": ("Cabinet", True),
    "Cabinet|-03.00|+00.40|+00.00": ("Cabinet", True),
    "Fridge|+03.00|+00.00|+00.00": ("Fridge", True),
    "Sink|+03.00|+00.90|+03.00|SinkBasin": ("SinkBasin", False),
    "Microwave|+00.00|+01.00|+03.00": ("Microwave", True),
    "DiningTable|-03.00|+00.75|+03.00": ("DiningTable", False),
    "Desk|+06.00|+00.75|+03.00": ("Desk", False),
}
FOOD = ["cleanable", "coolable", "heatable", "pickupable", "sliceable"]
OBJECTS = {
    "Apple|+00.10|+01.00|+00.10": ("Apple", FOOD, "CounterTop|+00.00|+00.95|+00.00"),
    "Knife|+00.20|+01.00|-00.10": ("Knife", ["cleanable", "pickupable"], "CounterTop|+00.00|+00.95|+00.00"),
    "Mug|+03.10|+01.20|+00.10": ("Mug", ["cleanable", "isReceptacleObject", "pickupable"], "Fridge|+03.00|+00.00|+00.00"),
    "Apple|-02.90|+00.80|+03.10": ("Apple", FOOD, "DiningTable|-03.00|+00.75|+03.00"),
    "Potato|-03.10|+00.80|+02.90": ("Potato", FOOD, "DiningTable|-03.00|+00.75|+03.00"),
    "Book|+06.10|+00.80|+03.10": ("Book", ["pickupable"], "Desk|+06.00|+00.75|+03.00"),
    "Sink|+03.00|+00.85|+03.00": ("Sink", [], None),
    "Faucet|+03.00|+01.20|+02.75": ("Faucet", [], None),
    "DeskLamp|+06.30|+00.80|+03.20": ("DeskLamp", ["toggleable"], "Desk|+06.00|+00.75|+03.00"),
}


def kitchen_facts() -> dict[str, Any]:
    return {
        "floor_plan": "TestKitchen",
        "receptacles": {rid: {"type": t, "openable": o, "location": "loc"} for rid, (t, o) in RECEPTACLES.items()},
        "objects": {oid: {"type": t, "props": p, "location": "loc"} for oid, (t, p, _) in OBJECTS.items()},
        "in_receptacle": [[oid, r] for oid, (_, _, r) in OBJECTS.items() if r],
        "other_facts": {},
        "in_receptacle_derived": [],
    }


def kitchen_task(task_type: str = "pick_and_place_simple", *, obj: str = "Apple", parent: str = "Fridge",
                 sliced: bool = False, toggle: str = "", mrecep: str = "", key: str = "test-kitchen") -> Task:
    record = {
        "task_type": task_type,
        "pddl_params": {"object_target": obj, "object_sliced": sliced, "parent_target": parent,
                        "toggle_target": toggle, "mrecep_target": mrecep},
        "scene": {"init_action": {"action": "TeleportFull", "x": 6.0, "y": 0.9, "z": 6.0, "rotation": 0, "horizon": 30},
                  "object_toggles": [], "dirty_and_empty": False, "object_poses": []},
        "plan": {"high_pddl": []},
    }
    return Task(id=f"test/{key}/{task_type}", benchmark="eb_alfred", subset="base", index=0, instruction="test",
                task_type=task_type, payload={"key": f"{key}-{task_type}-{obj}-{parent}-{sliced}", "record": record,
                                              "facts": kitchen_facts()})


@pytest.fixture
def twin() -> Any:
    from benchmarks.eb_alfred.twin import AlfredTwin

    env = AlfredTwin()
    yield env
    env.close()


def _run(env: Any, *actions: str) -> Any:
    """Step through named actions; returns the last StepResult."""
    result = None
    for name in actions:
        result = env.step(env.action_id(name))
    return result


@pytest.fixture
def make_task() -> Any:
    return kitchen_task


@pytest.fixture
def run() -> Any:
    return _run
