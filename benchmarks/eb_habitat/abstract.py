"""The abstract state s-bar of an EB-Habitat step, rendered from an immutable world snapshot.

It says what a perfect state abstractor would report from the robot's viewpoint: where the robot is
(its last navigation target) and which receptacles are within reach there, what it holds, which
objects lie on the receptacles within reach (contents of a closed refrigerator or drawer are hidden),
and the state of every door. Objects are named by category, as the pick skills name them.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from .scene import CAB_MARKERS, FRIDGE_MARKER, RECEPTACLE_TEXT, STATIC_ENTITIES
from .world import CONTAINER_IDX, NOWHERE, STATIC_INDEX, Entities

__all__ = ["Snapshot", "render_text", "render_state"]

Snapshot = tuple[int, int, tuple[int, ...], tuple[bool, ...]]
Reach = tuple[frozenset[int], ...]
_FRIDGE = STATIC_INDEX[FRIDGE_MARKER]
_CABS = tuple(STATIC_INDEX[m] for m in CAB_MARKERS)


def _the(entity: int) -> str:
    return "the " + RECEPTACLE_TEXT[STATIC_ENTITIES[entity]]


def _door(entity: int, doors: tuple[bool, ...]) -> str:
    """ " (closed)" / " (open)" after a receptacle behind a door or a door marker, else ""."""
    door = CONTAINER_IDX[entity] if CONTAINER_IDX[entity] != NOWHERE else entity
    if door == _FRIDGE or door in _CABS:
        return " (open)" if doors[door] else " (closed)"
    return ""


def _visible(reach: Reach, snap: Snapshot) -> list[int]:
    place, _, _, doors = snap
    return [e for e in sorted(reach[place]) if CONTAINER_IDX[e] == NOWHERE or doors[CONTAINER_IDX[e]]]


def _objects_on(ents: Entities, recep: tuple[int, ...], entity: int) -> str:
    counts = Counter(ents.categories[i] for i, r in enumerate(recep) if r == entity)
    return ", ".join(cat if n == 1 else f"{cat} (x{n})" for cat, n in sorted(counts.items()))


def render_text(ents: Entities, reach: Reach, snap: Snapshot) -> str:
    place, held, recep, doors = snap
    if place == NOWHERE:
        lines = ["Robot location: the start position (it has not navigated anywhere yet)."]
    else:
        near = [_the(e) + _door(e, doors) for e in sorted(reach[place]) if e != place]
        lines = [f"Robot location: {_the(place)}{_door(place, doors)}."]
        lines.append("Also within reach: " + (", ".join(near) if near else "nothing else") + ".")
    lines.append(f"Holding: {ents.categories[held] if held != NOWHERE else 'nothing'}.")
    if place != NOWHERE:
        seen = []
        for e in _visible(reach, snap):
            on = _objects_on(ents, recep, e)
            if on:
                seen.append(f"{_the(e)}: {on}")
        lines.append("Objects within reach: " + ("; ".join(seen) if seen else "none") + ".")
    fridge = "open" if doors[_FRIDGE] else "closed"
    cabs = ", ".join(
        f"{STATIC_ENTITIES[c].rsplit('_', 1)[1]} {'open' if doors[c] else 'closed'}" for c in _CABS
    )
    lines.append(f"Refrigerator: {fridge}. Cabinets: {cabs}.")
    return "\n".join(lines)


def render_state(ents: Entities, reach: Reach, snap: Snapshot) -> dict[str, Any]:
    """A JSON-serialisable snapshot for logs and tests."""
    place, held, recep, doors = snap
    return {
        "location": STATIC_ENTITIES[place] if place != NOWHERE else None,
        "holding": ents.names[held] if held != NOWHERE else None,
        "within_reach": [STATIC_ENTITIES[e] for e in sorted(reach[place])],
        "objects": {
            name: (STATIC_ENTITIES[r] if r != NOWHERE else "robot")
            for name, r in zip(ents.names, recep, strict=True)
        },
        "doors": {m: ("open" if doors[STATIC_INDEX[m]] else "closed") for m in (FRIDGE_MARKER, *CAB_MARKERS)},
    }
