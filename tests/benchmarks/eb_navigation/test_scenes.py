"""The approximated rooms of EmbodiedBench's floor plans: deterministic, start poses free, targets reachable."""

from __future__ import annotations

import shutil
from pathlib import Path

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.data import load_alfred_scene, load_scene_records
from benchmarks.eb_navigation.expert import heading_index, shortest_plan
from benchmarks.eb_navigation.geometry import (
    AGENT_HALF,
    Scene,
    SceneObject,
    compile_floor,
    obstacle_half,
    reachable_goal,
    room_type,
)
from benchmarks.eb_navigation.scenes import approximate_scene
from benchmarks.eb_navigation.tasks import scenes_for


def test_every_episode_starts_free_and_can_reach_its_target(eb_data_dir: Path) -> None:
    for subset in ADAPTER.subsets:
        for task in ADAPTER.load_tasks(eb_data_dir, subset):
            scene = Scene.from_dict(task.payload["scene"])
            pose = task.payload["record"]["agentPose"]
            x, z = pose["position"]["x"], pose["position"]["z"]
            assert scene.blocker(x, z) is None, task.id
            target = (
                task.payload["record"]["target_position"]["x"],
                task.payload["record"]["target_position"]["z"],
            )
            floor = compile_floor(scene, x, z)
            assert reachable_goal(floor, target), task.id
            plan = shortest_plan(floor, heading_index(pose["rotation"]), target)
            assert plan is not None and len(plan) <= 20, task.id


def test_approximation_is_deterministic_and_uses_alfred_facts_when_present(eb_data_dir: Path) -> None:
    grouped = load_scene_records(eb_data_dir)
    assert len(grouped) == 60 and all(len(r) == 5 for r in grouped.values())
    alfred = load_alfred_scene(eb_data_dir, "FloorPlan18")
    assert alfred is not None
    first = approximate_scene("FloorPlan18", grouped["FloorPlan18"], alfred)
    again = approximate_scene("FloorPlan18", grouped["FloorPlan18"], alfred)
    assert first == again
    types = {o.type for o in first.objects}
    assert {"Toaster", "Fridge", "CounterTop", "Cabinet"} <= types
    assert sum(o.type == "Toaster" for o in first.objects) == 1  # nav and ALFRED ids of one toaster merge
    assert "eb_alfred" in first.source
    # Where ALFRED has no file (FloorPlan211), the room comes from the navigation records alone.
    assert load_alfred_scene(eb_data_dir, "FloorPlan211") is None
    bare = approximate_scene("FloorPlan211", grouped["FloorPlan211"])
    assert [o.type for o in bare.objects] == ["GarbageCan"]
    assert bare.objects[0].half == (0.2, 0.2)
    xmin, zmin, xmax, zmax = bare.room
    assert xmax - xmin >= 3.0 and zmax - zmin >= 3.0


def test_hidden_duplicates_stay_visible_objects(eb_data_dir: Path) -> None:
    scene = scenes_for(eb_data_dir)["FloorPlan229"]
    statues = [o for o in scene.objects if o.type == "Statue"]
    assert {o.id for o in statues} == {"Statue|-02.98|+00.42|+02.36", "Statue|-00.18|+00.76|+01.55"}


def test_rooms_without_the_alfred_pack(tmp_path: Path, eb_data_dir: Path) -> None:
    shutil.copytree(eb_data_dir / "eb_navigation", tmp_path / "eb_navigation")
    scene = scenes_for(tmp_path)["FloorPlan18"]
    assert {o.type for o in scene.objects} == {"Toaster"}
    assert scene.source == "eb_navigation task records"
    tasks = ADAPTER.load_tasks(tmp_path, "base")
    assert all(t.expert_plan for t in tasks)


def test_obstacle_rules() -> None:
    assert obstacle_half("CounterTop", 0.9) == 0.4
    assert obstacle_half("Bread", 0.98) == 0.3  # stands in for the counter under it
    assert obstacle_half("Cabinet", 2.13) is None  # wall cabinet
    assert obstacle_half("Window", 1.0) is None
    assert room_type("FloorPlan12") == "kitchen"
    assert room_type("FloorPlan212") == "living_room"
    assert room_type("FloorPlan312") == "bedroom"


def test_obstacle_on_a_free_point_is_dropped_but_stays_visible() -> None:
    record = {
        "targetObjectType": "Bread",
        "targetObjectIds": "Bread|+02.00|+00.90|+00.00",
        "target_position": {"x": 2.0, "y": 0.9, "z": 0.0},
        "agentPose": {"position": {"x": 0.0, "y": 0.9, "z": 0.0}, "rotation": 90.0, "horizon": 0.0},
        "scene": "FloorPlan1",
        "object_to_hide": ["Chair|+00.10|+00.50|+00.00"],  # on top of the start pose
        "instruction": "navigate to the Bread in the room and be as close as possible to it",
    }
    scene = approximate_scene("FloorPlan1", [record])
    chair = next(o for o in scene.objects if o.type == "Chair")
    assert chair.half is None
    assert scene.blocker(0.0, 0.0) is None


def test_compile_floor_matches_the_exact_predicate() -> None:
    scene = Scene("t", (0.0, 0.0, 3.0, 3.0), (SceneObject("Box|1", "Box", 1.5, 0.5, 1.5, (0.3, 0.3)),))
    floor = compile_floor(scene, 0.5, 0.5)
    for i in range(-4, 12):
        for j in range(-4, 12):
            x, z = floor.position(i, j)
            assert ((i, j) in floor.free) == (scene.blocker(x, z) is None), (i, j)
    assert (0, 0) in floor.free
    assert scene.blocker(0.5 - 0.5, 0.5) == "Wall"  # x = 0.0 is closer than AGENT_HALF to the wall
    assert AGENT_HALF == 0.2
