"""Approximate rooms for EmbodiedBench's floor plans (the data has no room geometry).

How a floor plan's room is built, the same way every time (no randomness):

1. Known objects. Every record of that floor plan in all five subset files gives its target (type,
   objectId, target_position) and the ids in `object_to_hide` (EBNavEnv does not hide them, so they
   stay visible; their ids carry their positions). When the data pack also has
   `eb_alfred/scenes/<FloorPlan>.json` (34 of the 60 floor plans), its static objects and receptacles
   (counters, cabinets, tables, fridge, sofa, windows, ...) are added from their objectIds; an ALFRED
   object of the same type within 5 cm of one already known is the same object. ALFRED used AI2-THOR
   2.1 and EB-Navigation uses 5.0; where both name an object, the positions agree to 1 cm.
2. Obstacles. An object below 1.2 m that is not wall-mounted blocks a square around its position
   (geometry.obstacle_half: e.g. 0.4 m half-size for a counter top, 0.2 m for a garbage can, 0.3 m for
   a small object, which stands in for the counter or table it sits on).
3. Free floor. Every start pose, and every ALFRED interaction pose (where ALFRED's agent stood).
4. Room. The smallest rectangle holding every object (+0.25 m) and every free point (+0.45 m),
   widened to at least 3 m per side. Interior walls and L-shapes are not modelled.
5. Guarantees. An obstacle that covers a free point is dropped (the object stays visible). If a start
   pose then cannot reach a cell within 1.0 m of its target, the obstacle nearest the straight line from
   start to target is dropped, repeatedly, until it can. So every start pose is free and every episode
   is solvable in the twin, as it is in EmbodiedBench.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

from benchmarks.eb_navigation.data import parse_object_id
from benchmarks.eb_navigation.geometry import (
    Scene,
    SceneObject,
    bounding_room,
    compile_floor,
    obstacle_half,
    reachable_goal,
)

__all__ = ["approximate_scene"]

SAME_OBJECT_DISTANCE = 0.05


def _segment_distance(p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    ax, az = a
    dx, dz = b[0] - ax, b[1] - az
    length2 = dx * dx + dz * dz
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - az) * dz) / length2))
    return math.hypot(p[0] - (ax + t * dx), p[1] - (az + t * dz))


def _known_objects(records: Sequence[dict[str, Any]], alfred: dict[str, Any] | None) -> list[SceneObject]:
    objects: list[SceneObject] = []

    def add(object_id: str, obj_type: str, x: float, y: float, z: float) -> None:
        for o in objects:
            if o.id == object_id or (
                o.type == obj_type
                and abs(o.x - x) < SAME_OBJECT_DISTANCE
                and abs(o.z - z) < SAME_OBJECT_DISTANCE
            ):
                return
        half = obstacle_half(obj_type, y)
        objects.append(SceneObject(object_id, obj_type, x, y, z, (half, half) if half else None))

    for rec in records:
        p = rec["target_position"]
        add(rec["targetObjectIds"], rec["targetObjectType"], p["x"], p["y"], p["z"])
        for object_id in rec.get("object_to_hide", []):
            parsed = parse_object_id(object_id)
            if parsed is not None:
                add(object_id, *parsed)
    for object_id, obj_type, x, y, z in (alfred or {}).get("objects", []):
        add(object_id, obj_type, x, y, z)
    return objects


def _unblock_free_points(objects: list[SceneObject], free_points: Sequence[tuple[float, float]]) -> None:
    for k, o in enumerate(objects):
        if any(o.blocks(px, pz) for px, pz in free_points):
            objects[k] = replace(o, half=None)


def _make_reachable(scene: Scene, start: tuple[float, float], target: tuple[float, float]) -> Scene:
    while not reachable_goal(compile_floor(scene, *start), target):
        blocking = [k for k, o in enumerate(scene.objects) if o.half is not None]
        if not blocking:
            raise ValueError(f"{scene.name}: target {target} unreachable from {start} even in an empty room")
        k = min(
            blocking, key=lambda k: _segment_distance((scene.objects[k].x, scene.objects[k].z), start, target)
        )
        objects = list(scene.objects)
        objects[k] = replace(objects[k], half=None)
        scene = replace(scene, objects=tuple(objects))
    return scene


def approximate_scene(
    name: str, records: Sequence[dict[str, Any]], alfred: dict[str, Any] | None = None
) -> Scene:
    """The twin's room for one floor plan from all its task records (and ALFRED's facts, if given)."""
    if not records:
        raise ValueError(f"{name}: no task records to approximate the room from")
    objects = _known_objects(records, alfred)
    starts = sorted({(r["agentPose"]["position"]["x"], r["agentPose"]["position"]["z"]) for r in records})
    free_points = [*starts, *(alfred or {}).get("free_points", [])]
    _unblock_free_points(objects, free_points)
    source = "eb_navigation task records" + (" + eb_alfred scene facts" if alfred else "")
    scene = Scene(name, bounding_room(objects, free_points), tuple(objects), source)
    for rec in records:
        start = (rec["agentPose"]["position"]["x"], rec["agentPose"]["position"]["z"])
        target = (rec["target_position"]["x"], rec["target_position"]["z"])
        scene = _make_reachable(scene, start, target)
    return scene
