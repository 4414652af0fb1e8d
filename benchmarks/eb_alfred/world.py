"""The twin's mutable world state and the queries on it (visibility, containment, distance).

One `World` holds the per-episode state as flat lists indexed by object. The twin copies a list
before it first writes to it after a snapshot (copy-on-write), so a `Snapshot` handed to a lazy
Observation keeps showing the state of its own step even when it is read later.

Geometry, as the twin approximates AI2-THOR: the agent stands where the last `find` took it (the found
object's x/z, at ALFRED's agent height). An object is visible when it is within ALFRED's visibility
distance (1.5 m) of the agent on the floor plan (x/z; `find` tilts the camera, and object origins can
sit far below their visible surface, e.g. a bathtub basin's) and no closed openable receptacle
encloses it; a held object is always visible. What AI2-THOR also checks (the camera frustum,
occlusion) is not modelled. Distances that rank candidates are 3-D, as AI2-THOR reports them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from benchmarks.eb_alfred.scene import AGENT_Y, Scene

__all__ = ["World", "Snapshot", "VISIBILITY_DISTANCE"]

VISIBILITY_DISTANCE = 1.5
VISIBILITY_DISTANCE_SQ = VISIBILITY_DISTANCE**2


@dataclass(frozen=True, slots=True)
class Snapshot:
    """An immutable view of one step's state (the lists are never written after being shared)."""

    scene: Scene
    parent: list[int]
    pos: list[tuple[float, float, float]]
    is_open: list[bool]
    is_on: list[bool]
    active: list[bool]
    also_in: list[tuple[int, ...]]
    heated: frozenset[int]
    cooled: frozenset[int]
    cleaned: frozenset[int]
    holding: int
    agent: tuple[float, float, float]
    location: str


class World:
    """Queries shared by the twin's skills, the goal checks and the state text."""

    __slots__ = (
        "scene", "objs", "parent", "pos", "is_open", "is_on", "active", "also_in",
        "heated", "cooled", "cleaned", "holding", "agent", "location", "place",
    )

    def __init__(self, scene: Scene) -> None:
        init = scene.init
        self.scene = scene
        self.objs = scene.objects
        self.parent = list(init.parent)
        self.pos = [o.pos for o in scene.objects]
        self.is_open = list(init.is_open)
        self.is_on = list(init.is_on)
        self.active = list(init.active)
        self.also_in = list(init.also_in)
        self.heated: frozenset[int] = frozenset()
        self.cooled: frozenset[int] = frozenset()
        self.cleaned: frozenset[int] = frozenset()
        self.holding = -1
        self.agent = scene.agent_start
        self.location = "the starting position"
        # Receptacles under the agent's hands since the last find (where a dropped object lands).
        self.place: tuple[int, ...] = ()

    @classmethod
    def from_snapshot(cls, snap: Snapshot) -> World:
        w = cls.__new__(cls)
        w.scene, w.objs = snap.scene, snap.scene.objects
        w.parent, w.pos, w.is_open, w.is_on = snap.parent, snap.pos, snap.is_open, snap.is_on
        w.active, w.also_in = snap.active, snap.also_in
        w.heated, w.cooled, w.cleaned = snap.heated, snap.cooled, snap.cleaned
        w.holding, w.agent, w.location = snap.holding, snap.agent, snap.location
        w.place = ()
        return w

    def snapshot(self) -> Snapshot:
        return Snapshot(
            self.scene, self.parent, self.pos, self.is_open, self.is_on, self.active, self.also_in,
            self.heated, self.cooled, self.cleaned, self.holding, self.agent, self.location,
        )

    # -- queries -------------------------------------------------------------------------------
    def distance(self, i: int) -> float:
        return math.dist(self.agent, self.pos[i])

    def enclosed(self, i: int) -> bool:
        """Inside a closed openable receptacle (following the direct-parent chain)."""
        parent, is_open, objs = self.parent, self.is_open, self.objs
        j = parent[i]
        while j >= 0:
            if objs[j].openable and not is_open[j]:
                return True
            j = parent[j]
        return False

    def in_closed_holder(self, i: int) -> bool:
        """EB's penalty test: any receptacle listing i (chain or extra holders) is openable and closed."""
        if self.enclosed(i):
            return True
        return any(self.objs[r].openable and not self.is_open[r] for r in self.also_in[i])

    def visible(self, i: int) -> bool:
        if not self.active[i]:
            return False
        if i == self.holding:
            return True
        (ax, _, az), (x, _, z) = self.agent, self.pos[i]
        return (ax - x) ** 2 + (az - z) ** 2 <= VISIBILITY_DISTANCE_SQ and not self.enclosed(i)

    def holders(self, i: int) -> frozenset[int]:
        """The receptacles whose receptacleObjectIds list i: its parent chain plus extra holders."""
        out = list(self.also_in[i])
        j = self.parent[i]
        while j >= 0:
            out.append(j)
            j = self.parent[j]
        return frozenset(out)

    def contents(self, r: int) -> list[int]:
        """Active objects inside receptacle r, at any depth."""
        parent, active, also_in = self.parent, self.active, self.also_in
        found: list[int] = []
        frontier = [r]
        while frontier:
            k = frontier.pop()
            kids = [j for j, p in enumerate(parent) if p == k and active[j]]
            found += kids
            frontier += kids
        found += [j for j, extra in enumerate(also_in) if r in extra and active[j] and j not in found]
        return found

    def has_contents(self, r: int) -> bool:
        return any(p == r and self.active[j] for j, p in enumerate(self.parent)) or any(
            r in extra for extra in self.also_in
        )

    def carried(self) -> list[int]:
        """The held object and whatever is inside it."""
        return [] if self.holding < 0 else [self.holding, *self.contents(self.holding)]

    def agent_at(self, i: int) -> tuple[float, float, float]:
        x, _, z = self.pos[i]
        return (x, AGENT_Y, z)
