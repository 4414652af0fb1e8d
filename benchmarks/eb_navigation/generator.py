"""Procedurally generated EB-Navigation tasks, in EmbodiedBench's record format, deterministic per seed.

Generated like EmbodiedBench's own suite: episode k of every subset shares one room, target and start
pose, and the subsets differ only in how the instruction names the target (base: the type name with
EmbodiedBench's base template; common_sense: what it is for; visual_appearance: what it looks like;
complex_instruction: a request wrapped in unrelated remarks) and, for long_horizon, a start heading
turned 180 degrees so the target starts behind the agent. As in the real episodes, the start is
2.5-3.0 m from the target and (outside long_horizon) the target is in view.

A room is a rectangle (4-6 m a side) with furniture of its kind against the walls or in the middle,
floor objects against the walls, and small objects on furniture; the target is an object whose type
is unique in the room. Each task's expert plan is the twin's shortest plan (expert.py), so it succeeds
by construction; a room whose plan would exceed 16 actions (18 for long_horizon) is drawn again.
Everything depends only on (seed, episode index, subset), never on n.
"""

from __future__ import annotations

import random
from functools import lru_cache
from typing import Any, NamedTuple

from benchmarks.eb_navigation.actions import ACTION_TEXTS
from benchmarks.eb_navigation.catalog import AMBIENT, DESCRIPTIONS, FLOOR_OBJECTS, REQUESTS, ROOMS, Furniture
from benchmarks.eb_navigation.expert import shortest_plan
from benchmarks.eb_navigation.geometry import Scene, SceneObject, compile_floor
from benchmarks.eb_navigation.observe import Pose, visible_objects
from worldmind_local.env import Task

__all__ = ["generate_tasks", "BASE_TEMPLATE", "AGENT_Y"]

BASE_TEMPLATE = "navigate to the {type} in the room and be as close as possible to it"  # EB's base wording
AGENT_Y = 0.9
START_DISTANCE = (2.5, 3.0)
MAX_PLAN = 16
_Box = tuple[float, float, float, float]  # centre x, centre z, half x, half z


def _object_id(obj_type: str, x: float, y: float, z: float) -> str:
    return f"{obj_type}|{x:+06.2f}|{y:+06.2f}|{z:+06.2f}"


def _against_wall(rng: random.Random, room: _Box, along: float, depth: float) -> _Box:
    xmin, zmin, xmax, zmax = room
    wall = rng.randrange(4)
    if wall in (0, 2):  # north / south walls: long side along x
        hx, hz = along / 2, depth / 2
        cx = rng.uniform(xmin + hx + 0.05, xmax - hx - 0.05)
        cz = zmax - hz - 0.02 if wall == 0 else zmin + hz + 0.02
    else:
        hx, hz = depth / 2, along / 2
        cz = rng.uniform(zmin + hz + 0.05, zmax - hz - 0.05)
        cx = xmax - hx - 0.02 if wall == 1 else xmin + hx + 0.02
    return round(cx, 3), round(cz, 3), hx, hz


def _in_middle(rng: random.Random, room: _Box, size: tuple[float, float]) -> _Box | None:
    xmin, zmin, xmax, zmax = room
    hx, hz = (size[0] / 2, size[1] / 2) if rng.random() < 0.5 else (size[1] / 2, size[0] / 2)
    if xmax - xmin < 2 * hx + 2.0 or zmax - zmin < 2 * hz + 2.0:
        return None
    return round(rng.uniform(xmin + hx + 1.0, xmax - hx - 1.0), 3), round(rng.uniform(zmin + hz + 1.0, zmax - hz - 1.0), 3), hx, hz  # fmt: skip


def _overlaps(box: _Box, placed: list[_Box], gap: float = 0.15) -> bool:
    return any(
        abs(box[0] - b[0]) < box[2] + b[2] + gap and abs(box[1] - b[1]) < box[3] + b[3] + gap for b in placed
    )


def _place(rng: random.Random, room: _Box, placed: list[_Box], furniture: Furniture) -> _Box | None:
    for _ in range(30):
        if furniture.place == "wall":
            box: _Box | None = _against_wall(rng, room, *furniture.size)
        else:
            box = _in_middle(rng, room, furniture.size)
        if box is not None and not _overlaps(box, placed):
            placed.append(box)
            return box
    return None


def _build_room(rng: random.Random, kind: str, name: str) -> Scene:
    w, d = round(rng.uniform(4.0, 6.0), 2), round(rng.uniform(4.0, 6.0), 2)
    room = (round(-w / 2, 3), round(-d / 2, 3), round(w / 2, 3), round(d / 2, 3))
    placed: list[_Box] = []
    objects: list[SceneObject] = []
    ids: set[str] = set()

    def add(obj_type: str, x: float, y: float, z: float, half: tuple[float, float] | None) -> None:
        object_id = _object_id(obj_type, x, y, z)
        if object_id not in ids:
            ids.add(object_id)
            objects.append(SceneObject(object_id, obj_type, x, y, z, half))

    for furniture in ROOMS[kind]:
        box = _place(rng, room, placed, furniture)
        if box is None:
            continue
        cx, cz, hx, hz = box
        add(furniture.type, cx, furniture.height, cz, (hx, hz))
        for obj_type in rng.sample(furniture.holds, min(len(furniture.holds), rng.randint(1, 2))):
            x = round(rng.uniform(cx - hx + 0.1, cx + hx - 0.1), 3)
            z = round(rng.uniform(cz - hz + 0.1, cz + hz - 0.1), 3)
            add(obj_type, x, round(furniture.height + 0.05, 3), z, None)
    floor_objects = FLOOR_OBJECTS[kind]
    for obj_type, side in rng.sample(floor_objects, rng.randint(1, len(floor_objects))):
        box = _place(rng, room, placed, Furniture(obj_type, (side, side), 0.0, "wall"))
        if box is not None:
            add(obj_type, box[0], 0.0, box[1], (box[2], box[3]))
    return Scene(name, room, tuple(objects), "generated")


def _pick_start(rng: random.Random, scene: Scene, target: SceneObject) -> tuple[float, float, int] | None:
    xmin, zmin, xmax, zmax = scene.room
    tup = [(target.id, target.type, target.x, target.y, target.z)]
    for _ in range(300):
        x, z = round(rng.uniform(xmin + 0.3, xmax - 0.3), 1), round(rng.uniform(zmin + 0.3, zmax - 0.3), 1)
        if not START_DISTANCE[0] <= ((x - target.x) ** 2 + (z - target.z) ** 2) ** 0.5 <= START_DISTANCE[1]:
            continue
        if scene.blocker(x, z) is not None:
            continue
        headings = [h for h in range(4) if visible_objects(Pose(x, AGENT_Y, z, 90.0 * h, 0.0), tup)]
        if headings:
            return x, z, rng.choice(headings)
    return None


class _Episode(NamedTuple):
    """What every subset's task k shares: room kind, room, target, start (x, z, heading), expert plans."""

    kind: str
    scene: Scene
    target: SceneObject
    start: tuple[float, float, int]
    facing: tuple[int, ...]
    away: tuple[int, ...]


@lru_cache(maxsize=4096)
def _episode(seed: int, index: int) -> _Episode:
    rng = random.Random(f"eb_navigation:{seed}:{index}")
    kind = sorted(ROOMS)[rng.randrange(len(ROOMS))]
    for _ in range(500):
        scene = _build_room(rng, kind, f"Generated_{kind}_{seed}_{index}")
        movable = [o for o in scene.objects if o.type in DESCRIPTIONS]
        counts = {t: sum(o.type == t for o in movable) for t in {o.type for o in movable}}
        candidates = [o for o in movable if counts[o.type] == 1]
        if not candidates:
            continue
        target = rng.choice(candidates)
        start = _pick_start(rng, scene, target)
        if start is None:
            continue
        floor = compile_floor(scene, start[0], start[1])
        goal = (target.x, target.z)
        facing = shortest_plan(floor, start[2], goal, MAX_PLAN)
        away = shortest_plan(floor, (start[2] + 2) % 4, goal, MAX_PLAN + 2)
        if facing is not None and away is not None:
            return _Episode(kind, scene, target, start, tuple(facing), tuple(away))
    raise RuntimeError(f"could not generate EB-Navigation episode {index} for seed {seed}")


def _instruction(rng: random.Random, subset: str, obj_type: str) -> str:
    name, use, look = DESCRIPTIONS[obj_type]
    if subset == "common_sense":
        return rng.choice((
            f"I need {use}. Please go to that object and stay near it.",
            f"I am looking for {use}. Could you move right next to that object?",
            f"Help me find {use}: walk over to that object and stay beside it.",
        ))  # fmt: skip
    if subset == "visual_appearance":
        return rng.choice(
            (f"Go to the {look}.", f"Walk towards the {look}.", f"Find the {look} and stay close to it.")
        )
    if subset == "complex_instruction":
        first, second, last = rng.sample(AMBIENT, 3)
        return f"{first} {second} {rng.choice(REQUESTS).format(name=name)} {last}"
    return BASE_TEMPLATE.format(type=obj_type)


def _task(seed: int, subset: str, index: int) -> Task:
    episode = _episode(seed, index)
    scene, target, (x, z, heading) = episode.scene, episode.target, episode.start
    rng = random.Random(f"eb_navigation:{seed}:{index}:{subset}")
    long_horizon = subset == "long_horizon"
    record: dict[str, Any] = {
        "targetObjectType": target.type,
        "targetObjectIds": target.id,
        "target_position": {"x": target.x, "y": target.y, "z": target.z},
        "agentPose": {
            "position": {"x": x, "y": AGENT_Y, "z": z},
            "rotation": float(90 * ((heading + 2) % 4 if long_horizon else heading)),
            "horizon": 0.0,
        },
        "scene": scene.name,
        "object_to_hide": [],
        "instruction": _instruction(rng, subset, target.type),
    }
    plan = episode.away if long_horizon else episode.facing
    return Task(
        id=f"eb_navigation/generated-{seed}/{subset}/{index}",
        benchmark="eb_navigation",
        subset=subset,
        index=index,
        instruction=record["instruction"],
        task_type=episode.kind,
        payload={"record": record, "scene": scene.to_dict()},
        expert_plan=tuple(ACTION_TEXTS[a] for a in plan),
    )


def generate_tasks(seed: int, subset: str, n: int) -> list[Task]:
    """n generated tasks of one subset style; task k is the same for every n."""
    return [_task(seed, subset, index) for index in range(n)]
