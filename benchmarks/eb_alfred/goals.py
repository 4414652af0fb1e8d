"""ALFRED's goal conditions for the seven task types, as EmbodiedBench reports them.

EB's `task_success` is s == ts and its `task_progress` is s / ts, where (s, ts) come from the task
type's `goal_conditions_met`, evaluated on the *current* state after every step (so taking an object
back out lowers progress). Objects are matched the ALFRED way: a target name matches every object
whose objectId contains it as a substring ('Pot' also matches 'Potato|...'), among the objects with
the right property (pickupable / receptacle / toggleable). When the task wants a sliced object the
target becomes '<Obj>Sliced', which only slice pieces' ids contain, and ts grows by one (two for
pick_two_obj_and_place).

Heated / cooled / cleaned are ALFRED's bookkeeping sets (filled by the microwave, fridge and faucet
side effects), not object properties.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

__all__ = ["TASK_TYPES", "Goal", "GoalView", "build_goal", "conditions_met"]

TASK_TYPES = (
    "pick_and_place_simple",
    "pick_two_obj_and_place",
    "look_at_obj_in_light",
    "pick_clean_then_place_in_recep",
    "pick_heat_then_place_in_recep",
    "pick_cool_then_place_in_recep",
    "pick_and_place_with_movable_recep",
)
_TREATED = {
    "pick_clean_then_place_in_recep": "cleaned",
    "pick_heat_then_place_in_recep": "heated",
    "pick_cool_then_place_in_recep": "cooled",
}


class GoalView(Protocol):
    """The slice of twin state the goal checks read."""

    active: list[bool]
    is_on: list[bool]
    holding: int
    heated: frozenset[int]
    cooled: frozenset[int]
    cleaned: frozenset[int]

    def holders(self, i: int) -> frozenset[int]:
        """Receptacles that list object i in their receptacleObjectIds."""
        ...

    def visible(self, i: int) -> bool: ...


@dataclass(frozen=True, slots=True)
class Goal:
    """A task's targets, resolved once per scene to object indices (active or not)."""

    task_type: str
    sliced: bool
    objects: tuple[int, ...]
    sliced_objects: tuple[int, ...]
    parents: tuple[int, ...]
    mreceps: tuple[int, ...]
    toggles: tuple[int, ...]


def build_goal(task_type: str, params: Mapping[str, Any], objects: Sequence[Any]) -> Goal:
    """Resolve pddl_params against the scene's objects (each with object_id and property flags)."""
    if task_type not in TASK_TYPES:
        raise ValueError(f"unknown task type {task_type!r}")
    sliced = bool(params.get("object_sliced"))
    target = str(params.get("object_target") or "") + ("Sliced" if sliced else "")

    def match(name: str, flag: str) -> tuple[int, ...]:
        return tuple(o.idx for o in objects if name in o.object_id and getattr(o, flag))

    pickups = match(target, "pickupable")
    return Goal(
        task_type=task_type,
        sliced=sliced,
        objects=pickups,
        sliced_objects=tuple(i for i in pickups if "Sliced" in objects[i].object_id),
        parents=match(str(params.get("parent_target") or ""), "receptacle"),
        mreceps=match(str(params.get("mrecep_target") or ""), "pickupable"),
        toggles=match(str(params.get("toggle_target") or ""), "toggleable"),
    )


def conditions_met(goal: Goal, view: GoalView) -> tuple[int, int]:
    """(s, ts) for the current state."""
    active = view.active
    objs = [i for i in goal.objects if active[i]]
    s, ts = 0, 0
    if goal.sliced:
        n_sliced = sum(1 for i in goal.sliced_objects if active[i])
        if goal.task_type == "pick_two_obj_and_place":
            ts, s = 2, min(n_sliced, 2)
        else:
            ts, s = 1, int(n_sliced >= 1)
    parents = frozenset(r for r in goal.parents if active[r])
    return _CHECKS[goal.task_type](goal, view, objs, parents, s, ts)


def _simple(goal: Goal, view: GoalView, objs: list[int], parents: frozenset[int], s: int, ts: int) -> tuple[int, int]:
    placed = any(view.holders(i) & parents for i in objs)
    return s + int(placed), ts + 1


def _two(goal: Goal, view: GoalView, objs: list[int], parents: frozenset[int], s: int, ts: int) -> tuple[int, int]:
    counts = dict.fromkeys(parents, 0)
    for i in objs:
        for r in view.holders(i) & parents:
            counts[r] += 1
    return s + min(max(counts.values(), default=0), 2), ts + 2


def _look(goal: Goal, view: GoalView, objs: list[int], parents: frozenset[int], s: int, ts: int) -> tuple[int, int]:
    held = view.holding >= 0 and view.holding in objs
    lit = any(view.active[t] and view.is_on[t] and view.visible(t) for t in goal.toggles)
    return s + int(held) + int(lit), ts + 2


def _treated(goal: Goal, view: GoalView, objs: list[int], parents: frozenset[int], s: int, ts: int) -> tuple[int, int]:
    done: frozenset[int] = getattr(view, _TREATED[goal.task_type])
    in_place = {i for i in objs if view.holders(i) & parents}
    treated = {i for i in objs if i in done}
    return s + int(bool(in_place)) + int(bool(treated)) + int(bool(in_place & treated)), ts + 3


def _movable(goal: Goal, view: GoalView, objs: list[int], parents: frozenset[int], s: int, ts: int) -> tuple[int, int]:
    movables = [m for m in goal.mreceps if view.active[m]]
    holds = {m: any(m in view.holders(i) for i in objs) for m in movables}
    placed = {m: bool(view.holders(m) & parents) for m in movables}
    both = any(holds[m] and placed[m] for m in movables)
    return s + int(any(holds.values())) + int(any(placed.values())) + int(both), ts + 3


_CHECKS: dict[str, Callable[[Goal, GoalView, list[int], frozenset[int], int, int], tuple[int, int]]] = {
    "pick_and_place_simple": _simple,
    "pick_two_obj_and_place": _two,
    "look_at_obj_in_light": _look,
    "pick_clean_then_place_in_recep": _treated,
    "pick_heat_then_place_in_recep": _treated,
    "pick_cool_then_place_in_recep": _treated,
    "pick_and_place_with_movable_recep": _movable,
}
