"""What the agent sees, as text: objects in the camera's view with rough distance and bearing.

Shared by the twin (objects from its scene) and the real-simulator wrapper (objects from AI2-THOR's
metadata), so a planner sees the same kind of text on both. The camera follows EmbodiedBench's
controller: field of view 100 degrees (square image, so 100 both ways), visibility distance 10 m, eye
height about 0.675 m above the agent's position y, tilted by the horizon (positive = down, as in THOR).
An object is in view when its position falls inside that frustum; the twin has no occlusion.

One line per object type in view, nearest type first; several instances of a type share a line that
gives their number and the nearest one (kitchens show a dozen cabinets), e.g.::

    Objects in view (nearest first):
    - Cabinet (4 in view, nearest): about 1.0 m ahead, well to the right
    - Bread: about 2.5 m ahead, slightly to the left
    Camera: level.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

__all__ = [
    "Pose",
    "Sighting",
    "ObjectTuple",
    "visible_objects",
    "describe",
    "FIELD_OF_VIEW",
    "VISIBILITY_DISTANCE",
]

FIELD_OF_VIEW = 100.0
VISIBILITY_DISTANCE = 10.0
CAMERA_HEIGHT = 0.675
MAX_LISTED = 12  # object types per observation
_TAN_HALF_FOV = math.tan(math.radians(FIELD_OF_VIEW / 2))

ObjectTuple = tuple[str, str, float, float, float]  # (objectId, type, x, y, z)


@dataclass(frozen=True, slots=True)
class Pose:
    """Agent pose: position (THOR's agent y included), rotation (0 faces +z, 90 faces +x), horizon."""

    x: float
    y: float
    z: float
    rotation: float
    horizon: float


@dataclass(frozen=True, slots=True)
class Sighting:
    """One object in view: horizontal distance (m) and bearing (degrees, positive = to the right)."""

    type: str
    id: str
    x: float
    z: float
    distance: float
    bearing: float


def visible_objects(pose: Pose, objects: Iterable[ObjectTuple]) -> list[Sighting]:
    """The (id, type, x, y, z) objects inside the camera frustum, nearest first."""
    theta = math.radians(pose.rotation)
    fx, fz = math.sin(theta), math.cos(theta)
    rx, rz = fz, -fx
    pitch = math.radians(pose.horizon)
    cos_p, sin_p = math.cos(pitch), math.sin(pitch)
    cam_y = pose.y + CAMERA_HEIGHT
    seen: list[Sighting] = []
    for object_id, obj_type, x, y, z in objects:
        dx, dz = x - pose.x, z - pose.z
        distance = math.hypot(dx, dz)
        if distance > VISIBILITY_DISTANCE:
            continue
        lx, lz, ly = dx * rx + dz * rz, dx * fx + dz * fz, y - cam_y
        depth = lz * cos_p - ly * sin_p  # along the tilted camera axis
        up = ly * cos_p + lz * sin_p
        if depth <= 0 or abs(lx) > depth * _TAN_HALF_FOV or abs(up) > depth * _TAN_HALF_FOV:
            continue
        seen.append(Sighting(obj_type, object_id, x, z, distance, math.degrees(math.atan2(lx, lz))))
    seen.sort(key=lambda s: (s.distance, s.id))
    return seen


def _distance_words(distance: float) -> str:
    return f"about {max(0.5, round(distance * 2) / 2):.1f} m"


def _bearing_words(bearing: float) -> str:
    side = "right" if bearing > 0 else "left"
    if abs(bearing) <= 10:
        return "ahead"
    if abs(bearing) <= 30:
        return f"ahead, slightly to the {side}"
    return f"ahead, well to the {side}"


def _camera_words(horizon: float) -> str:
    if horizon == 0:
        return "Camera: level."
    direction = "down" if horizon > 0 else "up"
    return f"Camera: tilted {abs(horizon):g} degrees {direction}."


def describe(sightings: list[Sighting], horizon: float, blocked_ahead: str | None = None) -> str:
    """The observation text for objects in view, the camera tilt, and what is right in front, if anything."""
    lines: list[str] = []
    nearest: dict[str, Sighting] = {}
    counts: dict[str, int] = {}
    for s in sightings:  # nearest first, so the first of a type is its nearest
        nearest.setdefault(s.type, s)
        counts[s.type] = counts.get(s.type, 0) + 1
    if nearest:
        lines.append("Objects in view (nearest first):")
        for obj_type, s in list(nearest.items())[:MAX_LISTED]:
            label = obj_type if counts[obj_type] == 1 else f"{obj_type} ({counts[obj_type]} in view, nearest)"
            lines.append(f"- {label}: {_distance_words(s.distance)} {_bearing_words(s.bearing)}")
        if len(nearest) > MAX_LISTED:
            lines.append(f"- ... and {len(nearest) - MAX_LISTED} more kinds of objects further away")
    else:
        lines.append("No known objects are in view.")
    if blocked_ahead is not None:
        lines.append(f"Right in front (within 0.25 m): {blocked_ahead}; moving forward is blocked.")
    lines.append(_camera_words(horizon))
    return "\n".join(lines)
