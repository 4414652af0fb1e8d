"""EmbodiedBench's EB-Navigation episodes as Tasks.

A task's payload is `{"record": <the EB record, verbatim>, "scene": <the twin's room, Scene.to_dict()>}`,
so the twin needs nothing but the Task. Rooms are approximated once per floor plan from every
subset's records (scenes.py) and cached per data dir. `expert_plan` is the twin's shortest plan in
that approximated room (EmbodiedBench ships no expert plans for navigation); it shows the episode is
solvable in the twin, not what an expert would do in AI2-THOR.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

from benchmarks.eb_navigation.actions import ACTION_TEXTS, check_action_space_file
from benchmarks.eb_navigation.data import (
    SUBSETS,
    load_alfred_scene,
    load_records,
    load_scene_records,
    subset_path,
)
from benchmarks.eb_navigation.expert import heading_index, shortest_plan
from benchmarks.eb_navigation.geometry import Scene, compile_floor, room_type
from benchmarks.eb_navigation.scenes import approximate_scene
from worldmind_local.env import Task

__all__ = ["load_tasks", "scenes_for"]


def _fingerprint(data_dir: Path) -> tuple[tuple[str, int], ...]:
    paths = [subset_path(data_dir, s) for s in SUBSETS]
    paths += sorted((Path(data_dir) / "eb_alfred" / "scenes").glob("FloorPlan*.json"))
    return tuple((str(p), p.stat().st_mtime_ns) for p in paths if p.is_file())


@lru_cache(maxsize=8)
def _scenes_cached(data_dir: Path, fingerprint: tuple[tuple[str, int], ...]) -> dict[str, Scene]:
    grouped = load_scene_records(data_dir)
    return {
        name: approximate_scene(name, records, load_alfred_scene(data_dir, name))
        for name, records in sorted(grouped.items())
    }


def scenes_for(data_dir: Path) -> dict[str, Scene]:
    """The twin's room for every floor plan in the data dir's EB-Navigation files."""
    data_dir = Path(data_dir).resolve()
    return _scenes_cached(data_dir, _fingerprint(data_dir))


def _expert_plan(scene: Scene, record: dict[str, Any]) -> tuple[str, ...] | None:
    pose = record["agentPose"]
    floor = compile_floor(scene, float(pose["position"]["x"]), float(pose["position"]["z"]))
    target = (float(record["target_position"]["x"]), float(record["target_position"]["z"]))
    plan = shortest_plan(floor, heading_index(float(pose["rotation"])), target)
    return None if plan is None else tuple(ACTION_TEXTS[a] for a in plan)


def load_tasks(data_dir: Path, subset: str) -> list[Task]:
    """One subset's episodes in EmbodiedBench's order. Raises TaskDataError for a malformed file."""
    if subset not in SUBSETS:
        raise ValueError(f"unknown EB-Navigation subset {subset!r}; known: {', '.join(SUBSETS)}")
    action_space = Path(data_dir) / "eb_navigation" / "action_space.json"
    if action_space.is_file():
        check_action_space_file(action_space)
    records = load_records(data_dir, subset)
    scenes = scenes_for(data_dir)
    tasks = []
    for index, record in enumerate(records):
        scene = scenes[record["scene"]]
        tasks.append(
            Task(
                id=f"eb_navigation/{subset}/{index}",
                benchmark="eb_navigation",
                subset=subset,
                index=index,
                instruction=record["instruction"],
                task_type=room_type(record["scene"]),
                payload={"record": record, "scene": scene.to_dict()},
                expert_plan=_expert_plan(scene, record),
            )
        )
    return tasks
