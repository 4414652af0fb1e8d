"""The twin's mutable symbolic state and the per-episode entity table.

Everything is plain ints and lists so a step costs a few attribute reads: static entities (markers
and receptacles) are indexed by their position in ``scene.STATIC_ENTITIES`` (= their nav skill id),
objects by their position in the episode's `rigid_objs` list. The spatial tables of ``scene`` are
turned into index sets once, at import.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from .scene import CONTAINER_OF, HOME, REACH, STATIC_ENTITIES

__all__ = [
    "World",
    "Entities",
    "STATIC_INDEX",
    "REACH_IDX",
    "HOME_IDX",
    "CONTAINER_IDX",
    "NOWHERE",
    "reach_index",
]

STATIC_INDEX: dict[str, int] = {name: i for i, name in enumerate(STATIC_ENTITIES)}
NOWHERE = -1
_EMPTY: frozenset[int] = frozenset()


def reach_index(table: Mapping[str, frozenset[str]]) -> tuple[frozenset[int], ...]:
    """A place -> reachable entities table in index form (with the trailing "nowhere" entry)."""
    return (*(frozenset(STATIC_INDEX[e] for e in table[name]) for name in STATIC_ENTITIES), _EMPTY)


# Indexed by place; the trailing empty set is what index -1 (no place yet) reads.
HOME_IDX: tuple[frozenset[int], ...] = (
    *(frozenset(STATIC_INDEX[e] for e in HOME[name]) for name in STATIC_ENTITIES),
    _EMPTY,
)
REACH_IDX: tuple[frozenset[int], ...] = reach_index(REACH)
# The door marker enclosing each static entity, or -1 (index -1, "held", reads the trailing -1 too).
CONTAINER_IDX: tuple[int, ...] = (
    *(STATIC_INDEX[CONTAINER_OF[name]] if name in CONTAINER_OF else NOWHERE for name in STATIC_ENTITIES),
    NOWHERE,
)


class World:
    """Where the robot is, what it holds, where every object rests, which doors are open."""

    __slots__ = ("place", "held", "recep", "door_open", "reach", "seen_near", "start")

    def __init__(
        self,
        recep: list[int],
        door_open: list[bool],
        reach: tuple[frozenset[int], ...] = REACH_IDX,
        seen_near: tuple[frozenset[int], ...] | None = None,
    ) -> None:
        self.place = NOWHERE
        self.held = NOWHERE
        self.recep = recep
        self.start = tuple(recep)
        self.door_open = door_open
        self.reach = reach  # per place (trailing empty set for "nowhere"); the episode's own table
        # Per place, objects the episode's recordings show within reach while still where they started.
        self.seen_near = seen_near if seen_near is not None else (_EMPTY,) * len(reach)

    def snapshot(self) -> tuple[int, int, tuple[int, ...], tuple[bool, ...]]:
        """An immutable copy for lazily rendered observations."""
        return (self.place, self.held, tuple(self.recep), tuple(self.door_open))

    def near(self, obj: int) -> bool:
        """`robot_at(obj)`: held, on a receptacle within reach, or recorded within reach of this place."""
        recep = self.recep[obj]
        return (
            self.held == obj
            or recep in self.reach[self.place]
            or (obj in self.seen_near[self.place] and recep == self.start[obj])
        )

    def reachable(self, obj: int) -> bool:
        """Pickable: lying near the robot and not shut inside a closed refrigerator or drawer."""
        recep = self.recep[obj]
        if recep == NOWHERE or not self.near(obj):
            return False
        door = CONTAINER_IDX[recep]
        return door == NOWHERE or self.door_open[door]


@dataclass(frozen=True)
class Entities:
    """The episode's objects: instance names, categories, and lookups by name and category."""

    names: tuple[str, ...]
    categories: tuple[str, ...]
    start: tuple[int, ...]
    index: Mapping[str, int]
    by_category: Mapping[str, tuple[int, ...]]

    @classmethod
    def from_episode(cls, episode: Mapping[str, Any]) -> Entities:
        objs: Sequence[Mapping[str, Any]] = episode["rigid_objs"]
        names = tuple(o["instance_name"] for o in objs)
        cats = tuple(o["category"] for o in objs)
        by_cat: dict[str, list[int]] = {}
        for i, cat in enumerate(cats):
            by_cat.setdefault(cat, []).append(i)
        return cls(
            names=names,
            categories=cats,
            start=tuple(STATIC_INDEX[o["start_receptacle"]] for o in objs),
            index={n: i for i, n in enumerate(names)},
            by_category={c: tuple(v) for c, v in by_cat.items()},
        )
