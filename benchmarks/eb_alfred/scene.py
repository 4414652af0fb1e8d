"""The initial scene of one EB-ALFRED episode, built from exact facts plus a documented completion.

Exact (taken from the data as is):
  - the receptacle instances, their types and openability (ALFWorld's facts for the trial);
  - every object instance, its type and properties (pickupable, isReceptacleObject, sliceable, ...);
  - positions: AI2-THOR objectIds encode the object's position (`Apple|+01.20|+00.95|-00.31`), and
    the data sheet checked that every restored pose in tasks.json matches its id within 0.01 m;
  - the starting containment (`in_receptacle`, 4,027 facts) and the 3 derived facts;
  - the agent's start (the record's TeleportFull init_action) and the lamp states (object_toggles);
  - EB's toggleable types (Microwave, Faucet, DeskLamp, FloorLamp) and openable types.

Completed (the data does not say; each choice is a pure function of the task's facts, and the task key
seeds the only arbitrary choice, the order among equally good candidates):
  - an object with several containment facts (AI2-THOR reports every trigger box it sits in) gets the
    nearest one as its direct parent; the others stay as extra holders until the object moves;
  - `inReceptacleObject` nesting (an object inside a Bowl/Box/...) is kept when it is not circular
    and the inner object is not itself a movable receptacle (ALFWorld lists Pot-in-Pan and Pan-in-Pot);
  - a pickupable object with no containment fact (234 of ~5.4k) is put in the receptacle type the
    expert plan picks it from, if the plan says; else on the nearest non-openable receptacle within
    1 m that may hold its type (ALFRED's compatibility table); objects lower than 0.15 m, or with no
    such receptacle, lie on the floor;
  - openable receptacles start closed (AI2-THOR's default); Box and Laptop start open;
  - lamps start off unless object_toggles says otherwise; everything else starts off;
  - sinks without a faucet within 1.2 m get one 0.3 m above the basin (EB's scenes have one per sink);
  - a sliceable object breaks into a fixed number of pieces (typefacts `slice_counts`), whose ids
    follow AI2-THOR's `<parentId>|<Type>Sliced_<k>` form and which take the parent's place;
  - AI2-THOR's metadata order (which fixes EB's `Type_k` names) is taken as objectId order.

Not used: `dirty_and_empty` (EB's success and progress track cleaning in ALFRED's own set, not
the isDirty flag) and the ALFWorld interaction locations (the twin measures distances instead).
"""

from __future__ import annotations

import hashlib
import math
import random
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from benchmarks.eb_alfred.actions import InstanceNames, compile_action, instance_names
from benchmarks.eb_alfred.goals import Goal, build_goal
from benchmarks.eb_alfred.typefacts import TOGGLE_TYPES, type_facts

__all__ = ["SceneObject", "InitialState", "Scene", "build_scene", "cached_scene", "parse_position", "AGENT_Y"]

AGENT_Y = 0.9  # ALFRED's agent height; THOR distances are measured from the agent's body.
_FLOOR_Y = 0.15
_OPENABLE_OBJECTS = frozenset({"Box", "Laptop"})  # openable pickupable types (receptacles carry a flag)
_START_OPEN = _OPENABLE_OBJECTS


def parse_position(object_id: str) -> tuple[float, float, float]:
    parts = object_id.split("|")
    return float(parts[1]), float(parts[2]), float(parts[3])


@dataclass(frozen=True, slots=True)
class SceneObject:
    """Static facts of one object instance (never mutated during an episode)."""

    idx: int
    object_id: str
    type: str
    prefix: str  # objectId.split('|')[0], what EB's name lookup compares against
    pos: tuple[float, float, float]
    pickupable: bool
    receptacle: bool
    openable: bool
    toggleable: bool
    sliceable: bool
    inherited: bool  # five-part objectId (SinkBasin, BathtubBasin, slice pieces)
    slice_of: int = -1
    slices: tuple[int, ...] = ()


@dataclass(frozen=True, slots=True)
class InitialState:
    parent: tuple[int, ...]
    also_in: tuple[tuple[int, ...], ...]
    is_open: tuple[bool, ...]
    is_on: tuple[bool, ...]
    active: tuple[bool, ...]


@dataclass(frozen=True)
class Scene:
    key: str
    objects: tuple[SceneObject, ...]
    by_prefix: dict[str, tuple[int, ...]]
    init: InitialState
    agent_start: tuple[float, float, float]
    names: InstanceNames
    actions: tuple[str, ...]
    compiled: tuple[tuple[str, str], ...]
    index_of: dict[str, int]
    action_index: dict[str, int]
    display: tuple[str, ...]
    goal: Goal
    completed: tuple[str, ...] = field(default=())

    def first_of_type(self, obj_type: str) -> int:
        return next((o.idx for o in self.objects if o.type == obj_type), -1)


@dataclass
class _Raw:
    object_id: str
    type: str
    props: set[str]
    receptacle: bool
    openable: bool


def _raw_objects(facts: Mapping[str, Any]) -> dict[str, _Raw]:
    raw: dict[str, _Raw] = {}
    for oid, rec in facts["receptacles"].items():
        raw[oid] = _Raw(oid, rec["type"], set(), True, bool(rec["openable"]))
    for oid, rec in facts["objects"].items():
        props = set(rec.get("props", ()))
        raw[oid] = _Raw(oid, rec["type"], props, "isReceptacleObject" in props, rec["type"] in _OPENABLE_OBJECTS)
    return raw


def _add_missing_faucets(raw: dict[str, _Raw], notes: list[str]) -> None:
    faucets = [parse_position(o) for o, r in raw.items() if r.type == "Faucet"]
    for oid, r in list(raw.items()):
        if r.type != "SinkBasin":
            continue
        x, y, z = parse_position(oid)
        if any(math.dist((x, y, z), f) <= 1.2 for f in faucets):
            continue
        fid = f"Faucet|{x:+06.2f}|{y + 0.3:+06.2f}|{z:+06.2f}"
        raw[fid] = _Raw(fid, "Faucet", set(), False, False)
        notes.append(f"added {fid} by {oid}")


def _make_objects(raw: dict[str, _Raw]) -> list[SceneObject]:
    """All instances, slice pieces included (inactive until sliced), in objectId order."""
    slice_counts: dict[str, int] = type_facts()["slice_counts"]
    entries: dict[str, tuple[_Raw, str | None]] = {}
    for oid, r in raw.items():
        sliceable = "sliceable" in r.props and r.type in slice_counts
        entries[oid] = (r, None)
        for k in range(slice_counts[r.type] if sliceable else 0):
            sid = f"{oid}|{r.type}Sliced_{k}"
            entries[sid] = (_Raw(sid, f"{r.type}Sliced", {"pickupable"}, False, False), oid)
    order = sorted(entries)
    index = {oid: k for k, oid in enumerate(order)}
    pieces: dict[str, list[int]] = {}
    for oid in order:
        source = entries[oid][1]
        if source is not None:
            pieces.setdefault(source, []).append(index[oid])
    objects = []
    for k, oid in enumerate(order):
        r, source = entries[oid]
        objects.append(
            _new_object(k, r, oid, sliceable=oid in pieces, slice_of=index[source] if source else -1,
                        slices=tuple(pieces.get(oid, ())))
        )
    return objects


def _new_object(
    idx: int, r: _Raw, oid: str, *, sliceable: bool, slice_of: int = -1, slices: tuple[int, ...] = ()
) -> SceneObject:
    return SceneObject(
        idx=idx,
        object_id=oid,
        type=r.type,
        prefix=oid.split("|")[0],
        pos=parse_position(oid),
        pickupable="pickupable" in r.props,
        receptacle=r.receptacle,
        openable=r.openable,
        toggleable=r.type in TOGGLE_TYPES,
        sliceable=sliceable,
        inherited=len(oid.split("|")) == 5,
        slice_of=slice_of,
        slices=slices,
    )


def _plan_sources(record: Mapping[str, Any]) -> dict[str, str]:
    """objectId -> receptacle type the expert plan picks it from (when the plan says)."""
    out: dict[str, str] = {}
    for step in record.get("plan", {}).get("high_pddl", ()):
        pa = step.get("planner_action", {})
        if pa.get("action") == "PickupObject" and pa.get("coordinateReceptacleObjectId"):
            out.setdefault(pa["objectId"], pa["coordinateReceptacleObjectId"][0])
    return out


def _containment(
    objects: Sequence[SceneObject],
    index: Mapping[str, int],
    facts: Mapping[str, Any],
    record: Mapping[str, Any],
    rng: random.Random,
    notes: list[str],
) -> tuple[list[int], list[tuple[int, ...]]]:
    n = len(objects)
    holders: list[list[int]] = [[] for _ in range(n)]
    for o, r in list(facts.get("in_receptacle", ())) + list(facts.get("in_receptacle_derived", ())):
        if o in index and r in index and index[r] not in holders[index[o]]:
            holders[index[o]].append(index[r])
    parent = [-1] * n
    also: list[tuple[int, ...]] = [()] * n
    for i, hs in enumerate(holders):
        if hs:
            hs.sort(key=lambda r: (math.dist(objects[i].pos, objects[r].pos), objects[r].object_id))
            parent[i], also[i] = hs[0], tuple(hs[1:])
    movable = {o.idx for o in objects if o.receptacle and o.pickupable}
    for o, m in facts.get("other_facts", {}).get("inReceptacleObject", ()):
        if o in index and m in index:
            i, j = index[o], index[m]
            if i not in movable and j in movable and parent[j] != i:
                also[i] = tuple(r for r in (parent[i], *also[i]) if r >= 0 and r != parent[j])
                parent[i] = j
    sources = _plan_sources(record)
    for o in objects:
        if o.pickupable and o.slice_of < 0 and parent[o.idx] < 0 and not holders[o.idx]:
            parent[o.idx] = _complete_parent(o, objects, sources.get(o.object_id), rng)
            notes.append(f"{o.object_id} -> {objects[parent[o.idx]].object_id if parent[o.idx] >= 0 else 'floor'}")
    for o in objects:
        for s in o.slices:
            parent[s] = parent[o.idx]
    return parent, also


def _complete_parent(o: SceneObject, objects: Sequence[SceneObject], source_type: str | None, rng: random.Random) -> int:
    allowed: dict[str, list[str]] = type_facts()["receptacle_objects"]
    if source_type:
        cands = [r for r in objects if r.receptacle and not r.pickupable and r.type == source_type]
    elif o.pos[1] < _FLOOR_Y:
        return -1
    else:
        cands = [
            r
            for r in objects
            if r.receptacle and not r.pickupable and not r.openable and o.type in allowed.get(r.type, ())
            and math.dist((o.pos[0], o.pos[2]), (r.pos[0], r.pos[2])) <= 1.0
        ]
    if not cands:
        return -1
    tie = {r.idx: rng.random() for r in cands}
    return min(cands, key=lambda r: (round(math.dist(o.pos, r.pos), 3), tie[r.idx])).idx


def _names(objects: Sequence[SceneObject]) -> InstanceNames:
    receps = [(o.type, o.object_id) for o in objects if o.receptacle and o.slice_of < 0]
    picks = [(o.type, o.object_id) for o in objects if o.pickupable and not o.receptacle and o.slice_of < 0]
    return instance_names(receps, picks)


def seed_of(key: str) -> int:
    return int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "big")


def build_scene(key: str, record: Mapping[str, Any], facts: Mapping[str, Any]) -> Scene:
    """Build the initial scene of a task from its record (tasks.json format) and its scene facts."""
    notes: list[str] = []
    raw = _raw_objects(facts)
    _add_missing_faucets(raw, notes)
    objects = _make_objects(raw)
    index = {o.object_id: o.idx for o in objects}
    parent, also = _containment(objects, index, facts, record, random.Random(seed_of(key)), notes)
    toggles = {t["objectType"]: bool(t.get("isOn")) for t in record["scene"].get("object_toggles", ())}
    init = InitialState(
        parent=tuple(parent),
        also_in=tuple(also),
        is_open=tuple(o.openable and o.type in _START_OPEN for o in objects),
        is_on=tuple(toggles.get(o.type, False) for o in objects),
        active=tuple(o.slice_of < 0 for o in objects),
    )
    names = _names(objects)
    actions = tuple(names.actions)
    by_prefix: dict[str, list[int]] = {}
    for o in objects:
        by_prefix.setdefault(o.prefix.casefold(), []).append(o.idx)
    ia = record["scene"]["init_action"]
    display = tuple(names.id_to_name.get(o.object_id, o.type) for o in objects)
    return Scene(
        key=key,
        objects=tuple(objects),
        by_prefix={k: tuple(v) for k, v in by_prefix.items()},
        init=init,
        agent_start=(float(ia["x"]), AGENT_Y, float(ia["z"])),
        names=names,
        actions=actions,
        compiled=tuple(compile_action(a, names.name_to_id) for a in actions),
        index_of=index,
        action_index={a: k for k, a in enumerate(actions)},
        display=display,
        goal=build_goal(record["task_type"], record["pddl_params"], objects),
        completed=tuple(notes),
    )


_CACHE: OrderedDict[str, tuple[object, Scene]] = OrderedDict()
_CACHE_SIZE = 512


def cached_scene(key: str, record: Mapping[str, Any], facts: Mapping[str, Any]) -> Scene:
    """build_scene, memoised per task key (and the identity of its record). Scenes are immutable."""
    hit = _CACHE.get(key)
    if hit is not None and hit[0] is record:
        _CACHE.move_to_end(key)
        return hit[1]
    scene = build_scene(key, record, facts)
    _CACHE[key] = (record, scene)
    if len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return scene
