"""The twin's room: a rectangle with box obstacles, and the lattice of poses the agent can reach.

A scene (`Scene`) is a room rectangle on the xz plane plus known objects; an object with `half` set is
also an obstacle (an axis-aligned box of those half extents around its position). The agent is a
square of half-size AGENT_HALF (about AI2-THOR's agent radius). Headings are multiples of 90 degrees
and every move is 0.25 m along x or z, so from a start pose the agent can only ever stand on the
lattice `start + 0.25 * (i, j)`; `Floor` precomputes which lattice cells are free. Every obstacle
here is at least 0.35 m wide (0.75 m once inflated by the agent), so a 0.25 m move cannot jump over
one and checking the destination cell is the whole collision test.

EmbodiedBench's data gives no room geometry; `scenes.approximate_scene` builds it per floor plan, the same
way every time, from the facts the data pack has (scenes.py documents how).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

__all__ = [
    "AGENT_HALF",
    "SUCCESS_DISTANCE",
    "WALL_NAME",
    "SceneObject",
    "Scene",
    "Floor",
    "compile_floor",
    "obstacle_half",
    "room_type",
    "reaches",
    "reachable_goal",
    "bounding_room",
]

AGENT_HALF = 0.2
SUCCESS_DISTANCE = 1.0  # EmbodiedBench's SUCCESS_THRESHOLD (xz metres)
WALL_NAME = "Wall"
MOVE_STEP = 0.25
OBJECT_MARGIN = 0.25  # room edge beyond the outermost object position
FREE_POINT_MARGIN = 0.45  # room edge beyond a point where an agent stood
MIN_ROOM_SIDE = 3.0
UPPER_HEIGHT = 1.2  # objects above this (wall cabinets, windows, paintings) do not block the floor

# Approximate floor footprints (half extents in metres) of objects that block walking. A small object
# on a counter or table (Bread, Toaster, Laptop) stands in for the surface under it.
_HALF_BY_TYPE: dict[str, float] = {
    "ArmChair": 0.4, "Bed": 0.8, "Chair": 0.25, "CoffeeTable": 0.45, "CounterTop": 0.4, "Desk": 0.45,
    "DiningTable": 0.5, "Dresser": 0.4, "FloorLamp": 0.2, "Fridge": 0.4, "GarbageCan": 0.2,
    "HousePlant": 0.25, "LaundryHamper": 0.25, "Safe": 0.25, "Sink": 0.35, "Sofa": 0.6, "TVStand": 0.4,
    "Ottoman": 0.3, "Bathtub": 0.6, "Toilet": 0.3,
}  # fmt: skip
_DEFAULT_HALF = 0.3
_NEVER_BLOCKING = frozenset({
    "Blinds", "Curtains", "Faucet", "LightSwitch", "Mirror", "Painting", "Poster", "StoveKnob",
    "Television", "Window", "LaundryHamperLid", "ShowerHead", "TowelHolder", "HandTowelHolder",
})  # fmt: skip


@dataclass(frozen=True, slots=True)
class SceneObject:
    """A known object: what the agent can see; an obstacle too when `half` (x, z half extents) is set."""

    id: str
    type: str
    x: float
    y: float
    z: float
    half: tuple[float, float] | None = None

    def blocks(self, px: float, pz: float) -> bool:
        """Whether the agent square centred at (px, pz) overlaps this obstacle (touching is allowed)."""
        if self.half is None:
            return False
        return abs(px - self.x) < self.half[0] + AGENT_HALF and abs(pz - self.z) < self.half[1] + AGENT_HALF


@dataclass(frozen=True, slots=True)
class Scene:
    """A room: rectangle (xmin, zmin, xmax, zmax), known objects, and where the approximation came from."""

    name: str
    room: tuple[float, float, float, float]
    objects: tuple[SceneObject, ...]
    source: str = ""

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Scene:
        """The inverse of to_dict (a Task payload's "scene")."""
        objects = []
        for o in d["objects"]:
            x, y, z = (float(v) for v in o["position"])
            half = (float(o["half"][0]), float(o["half"][1])) if o.get("half") else None
            objects.append(SceneObject(o["id"], o["type"], x, y, z, half))
        xmin, zmin, xmax, zmax = (float(v) for v in d["room"])
        return cls(d["name"], (xmin, zmin, xmax, zmax), tuple(objects), d.get("source", ""))

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "room": list(self.room),
            "objects": [
                {
                    "id": o.id,
                    "type": o.type,
                    "position": [o.x, o.y, o.z],
                    "half": list(o.half) if o.half else None,
                }
                for o in self.objects
            ],
            "source": self.source,
        }

    def inside_room(self, px: float, pz: float) -> bool:
        xmin, zmin, xmax, zmax = self.room
        return xmin + AGENT_HALF <= px <= xmax - AGENT_HALF and zmin + AGENT_HALF <= pz <= zmax - AGENT_HALF

    def blocker(self, px: float, pz: float) -> str | None:
        """The name of what stops the agent standing at (px, pz): a wall, the nearest obstacle, or None."""
        if not self.inside_room(px, pz):
            return WALL_NAME
        hits = [o for o in self.objects if o.blocks(px, pz)]
        if not hits:
            return None
        return min(hits, key=lambda o: (o.x - px) ** 2 + (o.z - pz) ** 2).type


@dataclass(frozen=True, slots=True)
class Floor:
    """The free lattice cells of one scene for one start position (cell (i, j) = start + 0.25 * (i, j))."""

    x0: float
    z0: float
    free: frozenset[tuple[int, int]]

    def position(self, i: int, j: int) -> tuple[float, float]:
        return self.x0 + MOVE_STEP * i, self.z0 + MOVE_STEP * j


def _cell_range(lo: float, hi: float, origin: float) -> range:
    return range(math.floor((lo - origin) / MOVE_STEP) - 1, math.ceil((hi - origin) / MOVE_STEP) + 2)


@lru_cache(maxsize=512)
def compile_floor(scene: Scene, x0: float, z0: float) -> Floor:
    """Mark every lattice cell inside the room that no obstacle covers."""
    xmin, zmin, xmax, zmax = scene.room
    free: set[tuple[int, int]] = set()
    for i in _cell_range(xmin, xmax, x0):
        px = x0 + MOVE_STEP * i
        for j in _cell_range(zmin, zmax, z0):
            pz = z0 + MOVE_STEP * j
            if scene.inside_room(px, pz):
                free.add((i, j))
    for o in scene.objects:
        if o.half is None:
            continue
        for i in _cell_range(o.x - o.half[0] - AGENT_HALF, o.x + o.half[0] + AGENT_HALF, x0):
            for j in _cell_range(o.z - o.half[1] - AGENT_HALF, o.z + o.half[1] + AGENT_HALF, z0):
                if (i, j) in free and o.blocks(x0 + MOVE_STEP * i, z0 + MOVE_STEP * j):
                    free.discard((i, j))
    return Floor(x0, z0, frozenset(free))


def reaches(position: tuple[float, float], target: tuple[float, float]) -> bool:
    """EmbodiedBench's success test: xz distance to the target position at most 1.0 m."""
    return math.sqrt((position[0] - target[0]) ** 2 + (position[1] - target[1]) ** 2) <= SUCCESS_DISTANCE


def reachable_goal(floor: Floor, target: tuple[float, float]) -> bool:
    """Whether some free cell connected to the start cell (0, 0) is within success distance of the target."""
    if (0, 0) not in floor.free:
        return False
    seen, queue = {(0, 0)}, deque([(0, 0)])
    while queue:
        i, j = queue.popleft()
        if reaches(floor.position(i, j), target):
            return True
        for n in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
            if n in floor.free and n not in seen:
                seen.add(n)
                queue.append(n)
    return False


def obstacle_half(obj_type: str, y: float) -> float | None:
    """Footprint half-size of an object of this type at height y, or None when it does not block."""
    if obj_type in _NEVER_BLOCKING or y > UPPER_HEIGHT:
        return None
    return _HALF_BY_TYPE.get(obj_type, _DEFAULT_HALF)


def room_type(scene_name: str) -> str:
    """iTHOR's numbering: FloorPlan1-30 kitchens, 201-230 living rooms, 301-330 bedrooms, 401-430 bathrooms."""
    digits = scene_name.removeprefix("FloorPlan")
    if not digits.isdigit():
        return "room"
    n = int(digits)
    return {0: "kitchen", 2: "living_room", 3: "bedroom", 4: "bathroom"}.get(n // 100, "room")


def bounding_room(
    objects: Sequence[SceneObject], free_points: Iterable[tuple[float, float]]
) -> tuple[float, float, float, float]:
    """The smallest rectangle holding every object (plus a margin) and every free point (plus room for the
    agent), widened symmetrically to at least MIN_ROOM_SIDE per side (iTHOR rooms are rarely narrower)."""
    xs: list[float] = []
    zs: list[float] = []
    for o in objects:
        xs += [o.x - OBJECT_MARGIN, o.x + OBJECT_MARGIN]
        zs += [o.z - OBJECT_MARGIN, o.z + OBJECT_MARGIN]
    for px, pz in free_points:
        xs += [px - FREE_POINT_MARGIN, px + FREE_POINT_MARGIN]
        zs += [pz - FREE_POINT_MARGIN, pz + FREE_POINT_MARGIN]
    xmin, xmax, zmin, zmax = min(xs), max(xs), min(zs), max(zs)
    if xmax - xmin < MIN_ROOM_SIDE:
        pad = (MIN_ROOM_SIDE - (xmax - xmin)) / 2
        xmin, xmax = xmin - pad, xmax + pad
    if zmax - zmin < MIN_ROOM_SIDE:
        pad = (MIN_ROOM_SIDE - (zmax - zmin)) / 2
        zmin, zmax = zmin - pad, zmax + pad
    return (round(xmin, 4), round(zmin, 4), round(xmax, 4), round(zmax, 4))
