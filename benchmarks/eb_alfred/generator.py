"""Procedurally generated EB-ALFRED tasks: new rooms and tasks in the data pack's record format.

Each task is a (task record, scene facts) pair like a real one, including ALFRED-style expert
subgoals (`plan.high_pddl`), so the same scene builder, twin and expert translation run on it. Task
i of (seed, subset) depends only on those three values (its own RNG), so a suite is identical for
a seed whatever n is, and byte-identical across runs. A sampled task is kept only if it does not
start half-done and its translated expert plan succeeds on the twin within EB's 30 steps.
"""

from __future__ import annotations

import random
from typing import Any

from benchmarks.eb_alfred.expert import ExpertError, expert_plan
from benchmarks.eb_alfred.goals import conditions_met
from benchmarks.eb_alfred.layouts import ROOMS, Room, build_room
from benchmarks.eb_alfred.phrasing import TaskWords, instruction
from benchmarks.eb_alfred.scene import build_scene
from benchmarks.eb_alfred.typefacts import MOVABLE_RECEPTACLES, SLICE_TYPES, type_facts
from benchmarks.eb_alfred.world import World
from worldmind_local.env import Task

__all__ = ["generate_tasks", "generate_task", "GenerationError"]

_ROOMS_FOR = {
    "pick_and_place_simple": ("Kitchen", "LivingRoom", "Bedroom", "Bathroom"),
    "pick_two_obj_and_place": ("Kitchen", "LivingRoom", "Bedroom", "Bathroom"),
    "look_at_obj_in_light": ("LivingRoom", "Bedroom"),
    "pick_clean_then_place_in_recep": ("Kitchen", "Bathroom"),
    "pick_heat_then_place_in_recep": ("Kitchen",),
    "pick_cool_then_place_in_recep": ("Kitchen",),
    "pick_and_place_with_movable_recep": ("Kitchen", "LivingRoom", "Bedroom"),
}
_TREAT = {
    "pick_clean_then_place_in_recep": ("Cleanable", "SinkBasin", "CleanObject"),
    "pick_heat_then_place_in_recep": ("Heatable", "Microwave", "HeatObject"),
    "pick_cool_then_place_in_recep": ("Coolable", "Fridge", "CoolObject"),
}
_STYLE = {"long_horizon": "base"}
_MAX_TRIES = 40


class GenerationError(RuntimeError):
    """No valid task could be sampled (should not happen; it means a generator bug)."""


def _types_in(room: Room) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for rid in room.receptacles:
        out.setdefault(room.facts["receptacles"][rid]["type"], []).append(rid)
    return out


def _holders(room: Room, obj_type: str, exclude: tuple[str, ...] = ()) -> list[str]:
    return [r for r in room.receptacles if room.can_hold(r, obj_type) and room.facts["receptacles"][r]["type"] not in exclude]


def _step(action: str, **fields: Any) -> dict[str, Any]:
    return {"discrete_action": {"action": action, "args": []}, "planner_action": {"action": action, **fields}}


class _Sampler:
    """Builds one task: room, objects, targets and ALFRED-style subgoals."""

    def __init__(self, rng: random.Random, task_type: str, long: bool) -> None:
        self.rng, self.task_type, self.long = rng, task_type, long
        self.room = build_room(rng.choice(_ROOMS_FOR[task_type]), rng, want_lamp=task_type == "look_at_obj_in_light")
        self.plan: list[dict[str, Any]] = []
        self.words: dict[str, Any] = {}

    def pick_source(self, obj_type: str, exclude: tuple[str, ...]) -> str:
        choices = _holders(self.room, obj_type, exclude)
        closed = [r for r in choices if self.room.facts["receptacles"][r]["openable"]]
        if self.long and closed and self.rng.random() < 0.7:
            return self.rng.choice(closed)
        if not choices:
            raise GenerationError(f"no receptacle for {obj_type}")
        return self.rng.choice(choices)

    def distractors(self, k: int) -> None:
        pool = [t for t in _room_objects(self.room) if t != self.words.get("obj")]
        for _ in range(k):
            t = self.rng.choice(pool)
            holders = _holders(self.room, t)
            if holders:
                self.room.add_object(t, self.rng.choice(holders), self.rng)

    def carry(self, obj: str, target: str) -> None:
        self.plan += [_step("GotoLocation", location="loc|0|0|0|30"), _step("PickupObject", objectId=obj)]
        self.plan += [_step("GotoLocation", location="loc|0|0|0|30"), _step("PutObject", objectId=obj, receptacleObjectId=target)]

    def slice_first(self, obj: str, obj_type: str) -> str:
        """Fetch a knife, slice the object, leave the knife; returns the piece to use."""
        knife_type = self.rng.choice(("Knife", "ButterKnife"))
        knife = self.room.add_object(knife_type, self.pick_source(knife_type, ()), self.rng)
        self.plan += [_step("GotoLocation", location="loc"), _step("PickupObject", objectId=knife)]
        self.plan += [_step("GotoLocation", location="loc"), _step("SliceObject", objectId=obj)]
        drop = self.rng.choice(_holders(self.room, knife_type, ("Fridge", "Microwave")))
        self.plan += [_step("GotoLocation", location="loc"), _step("PutObject", objectId=knife, receptacleObjectId=drop)]
        return f"{obj}|{obj_type}Sliced_{self.rng.randint(0, 2)}"


def _room_objects(room: Room) -> list[str]:
    return list(ROOMS[room.kind]["objects"])


def _choose_object(s: _Sampler) -> tuple[str, bool]:
    facts = type_facts()
    pool = _room_objects(s.room)
    if s.task_type in _TREAT:
        ok = set(facts["action_objects"][_TREAT[s.task_type][0]])
        pool = [t for t in pool if t in ok]
    if s.task_type == "pick_and_place_with_movable_recep":
        pool = [t for t in pool if t not in MOVABLE_RECEPTACLES]
    sliceable = [t for t in pool if t in SLICE_TYPES]
    if sliceable and s.task_type != "look_at_obj_in_light" and s.rng.random() < (0.6 if s.long else 0.2):
        return s.rng.choice(sliceable), True
    return s.rng.choice(pool), False


def _sample(rng: random.Random, subset: str) -> tuple[dict[str, Any], dict[str, Any], TaskWords]:
    long = subset == "long_horizon"
    types = tuple(_TREAT) if long else tuple(_ROOMS_FOR)
    s = _Sampler(rng, rng.choice(types), long)
    obj_type, sliced = _choose_object(s)
    s.words["obj"] = obj_type
    kinds = _types_in(s.room)
    treat = _TREAT.get(s.task_type)
    avoid = ("Fridge", "Microwave", "SinkBasin") if treat else ()
    parent_pool = [t for t in kinds if t not in avoid and any(s.room.can_hold(r, obj_type + ("Sliced" if sliced else "")) for r in kinds[t])]
    mrecep = ""
    if s.task_type == "pick_and_place_with_movable_recep":
        options = [m for m in sorted(MOVABLE_RECEPTACLES) if m in _room_objects(s.room) and obj_type in type_facts()["receptacle_objects"].get(m, ())]
        mrecep = s.rng.choice(options) if options else ""
        parent_pool = [t for t in kinds if mrecep and any(s.room.can_hold(r, mrecep) for r in kinds[t])]
    if not parent_pool and s.task_type != "look_at_obj_in_light":
        raise GenerationError("no parent receptacle")
    parent = s.rng.choice(parent_pool) if parent_pool else ""
    source = s.pick_source(obj_type, (parent,))
    obj = s.room.add_object(obj_type, source, rng)
    whole = obj
    if sliced:
        obj = s.slice_first(obj, obj_type)
    target = rng.choice(kinds[parent]) if parent else ""
    lamp = ""
    if s.task_type == "look_at_obj_in_light":
        lamp_id = next(o for o, f in s.room.facts["objects"].items() if f["type"] in ("DeskLamp", "FloorLamp"))
        lamp = s.room.facts["objects"][lamp_id]["type"]
        s.plan += [_step("GotoLocation", location="loc"), _step("PickupObject", objectId=obj)]
        s.plan += [_step("GotoLocation", location="loc"), _step("ToggleObject", objectId=lamp_id)]
    elif treat:
        appliance = rng.choice(kinds[treat[1]])
        s.plan += [_step("GotoLocation", location="loc"), _step("PickupObject", objectId=obj)]
        s.plan += [_step("GotoLocation", location="loc"), _step(treat[2], objectId=appliance)]
        s.plan += [_step("GotoLocation", location="loc"), _step("PutObject", objectId=obj, receptacleObjectId=target)]
    elif mrecep:
        holder = s.room.add_object(mrecep, s.pick_source(mrecep, (parent,)), rng)
        s.carry(obj, holder)
        s.carry(holder, target)
    else:
        s.carry(obj, target)
        if s.task_type == "pick_two_obj_and_place":
            second = f"{whole}|{obj_type}Sliced_3" if sliced else s.room.add_object(obj_type, s.pick_source(obj_type, (parent,)), rng)
            s.carry(second, target)
    s.distractors(rng.randint(3, 8))
    s.plan.append(_step("NoOp"))
    for k, step in enumerate(s.plan):
        step["high_idx"] = k
    record = {
        "task_id": "", "split": "generated", "task_type": s.task_type,
        "pddl_params": {"object_target": obj_type, "object_sliced": sliced, "parent_target": parent,
                        "mrecep_target": mrecep, "toggle_target": lamp},
        "scene": {"floor_plan": s.room.facts["floor_plan"], "scene_num": 0, "init_action": {
            "action": "TeleportFull", "x": round(s.room.agent[0], 2), "y": 0.9, "z": round(s.room.agent[1], 2),
            "rotation": 0, "horizon": 30}, "dirty_and_empty": False,
            "object_toggles": [{"objectType": lamp, "isOn": False}] if lamp else [], "object_poses": []},
        "plan": {"high_pddl": s.plan},
    }
    src_type = s.room.facts["receptacles"][source]["type"]
    station = s.room.station_of[source]
    neighbours = sorted({s.room.facts["receptacles"][r]["type"] for r in s.room.receptacles if s.room.station_of[r] == station} - {src_type})
    words = TaskWords(s.task_type, obj_type, sliced, parent, mrecep, lamp, src_type, rng.choice(neighbours) if neighbours else "")
    return record, s.room.facts, words


def generate_task(seed: int, subset: str, index: int) -> Task:
    rng = random.Random(f"eb_alfred|{seed}|{subset}|{index}")
    key = f"generated-{seed}-{subset}-{index}"
    for _ in range(_MAX_TRIES):
        try:
            record, facts, words = _sample(rng, subset)
            scene = build_scene(key, record, facts)
            s, _ts = conditions_met(scene.goal, World(scene))
            if s:
                continue
            plan = expert_plan(scene, record["plan"]["high_pddl"])
        except (GenerationError, ExpertError, IndexError, StopIteration):
            continue
        if len(plan) > 30:
            continue
        text = instruction(words, _STYLE.get(subset, subset), rng)
        record["task_id"] = key
        return Task(
            id=f"eb_alfred/generated-{seed}/{subset}/{index}", benchmark="eb_alfred", subset=subset, index=index,
            instruction=text, task_type=record["task_type"],
            payload={"key": key, "record": record, "facts": facts},
            expert_plan=tuple(plan),
        )
    raise GenerationError(f"could not sample a valid task for seed {seed}, subset {subset}, index {index}")


def generate_tasks(seed: int, subset: str, n: int) -> list[Task]:
    return [generate_task(seed, subset, i) for i in range(n)]
