"""Task families for the generated EB-Habitat suite: clutter, goal expression, instruction.

Each family fills a ``Clutter`` (the episode's objects) and returns a ``Draft``: the instruction, the
goal in EmbodiedBench's expression format, the start predicates and the sampled entities. The
constraints that make a draft solvable and non-trivial are kept here, next to the goal they serve:
the target category is never already at its destination, a category to clear away has exactly one
instance, and "every X" tasks put every X on the source.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from . import phrasing as say
from .scene import (
    CATEGORIES,
    CATEGORY_ASSETS,
    DRAWER_LEFT,
    DRAWER_RIGHT,
    FRIDGE,
    NOMINAL_POSITION,
    OPEN_AIR_RECEPTACLES,
    RECEPTACLE_LOOKS,
)

__all__ = ["Clutter", "Draft", "SUBSET_STYLES"]

FRIDGE_STATE = {True: "opened_fridge(fridge_push_point)", False: "closed_fridge(fridge_push_point)"}
Namer = Callable[[str], str]


class Clutter:
    """Objects of one episode: (asset, category, receptacle); instance numbers count per asset."""

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng
        self.items: list[tuple[str, str, str]] = []

    def add(self, category: str, recep: str, copies: int = 1) -> None:
        for _ in range(copies):
            self.items.append((self.rng.choice(CATEGORY_ASSETS[category]), category, recep))

    def fill(self, avoid: frozenset[str] = frozenset()) -> None:
        """Random clutter (20-30 objects in all) of categories not in `avoid` on open-air receptacles."""
        total = self.rng.randint(20, 30)
        pool = [c for c in CATEGORIES if c not in avoid]
        while len(self.items) < total:
            self.add(self.rng.choice(pool), self.rng.choice(OPEN_AIR_RECEPTACLES))

    def records(self) -> list[dict[str, Any]]:
        """`rigid_objs` entries; positions are nominal (around the receptacle), the twin never reads them."""
        counters: dict[str, int] = {}
        out = []
        for asset, category, recep in sorted(self.items, key=lambda item: item[0]):
            n = counters[asset] = counters.get(asset, -1) + 1
            x, y, z = (v + round(self.rng.uniform(-0.3, 0.3), 4) for v in NOMINAL_POSITION[recep])
            rows = [[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]]
            out.append({
                "asset": f"{asset}.object_config.json", "category": category, "position": [x, y, z],
                "transform": rows, "instance_name": f"{asset}_:{n:04d}", "start_receptacle": recep,
            })  # fmt: skip
        return out


@dataclass
class Draft:
    instruction: str
    goal: dict[str, Any]
    instruct_id: str
    entities: dict[str, str]
    start_preds: list[str] = field(default_factory=list)


def _exists(subs: list[Any], *cats: str) -> dict[str, Any]:
    inputs = [{"name": v, "expr_type": c} for v, c in zip("XYZ", cats, strict=False)]
    return {"expr_type": "AND", "quantifier": "EXISTS", "inputs": inputs, "sub_exprs": subs}


def _elsewhere(rng: random.Random, than: str) -> str:
    return rng.choice([r for r in OPEN_AIR_RECEPTACLES if r != than])


def _look(recep: str) -> str:
    return RECEPTACLE_LOOKS[recep]


def move(rng: random.Random, cl: Clutter, obj: Namer = str, dst_name: Namer = _look,
         dst_pool: tuple[str, ...] = OPEN_AIR_RECEPTACLES, phrases: tuple[str, ...] = say.MOVE) -> Draft:  # fmt: skip
    cat, dst = rng.choice(CATEGORIES), rng.choice(dst_pool)
    src = _elsewhere(rng, dst)
    cl.add(cat, src, copies=rng.randint(1, 2))
    cl.fill(frozenset({cat}))
    text = rng.choice(phrases).format(obj=say.a_noun(obj(cat)), src=_look(src), dst=dst_name(dst))
    entities = {"source_receptacle_name": src, "target_receptacle_name": dst, "target_object_name": cat}
    return Draft(text, _exists([f"on_top(X, {dst})", "not_holding()"], cat), "gen_move", entities)


def remove(rng: random.Random, cl: Clutter) -> Draft:
    cat, src = rng.choice(CATEGORIES), rng.choice(OPEN_AIR_RECEPTACLES)
    cl.add(cat, src)
    cl.fill(frozenset({cat}))
    nand = {"expr_type": "NAND", "quantifier": "EXISTS", "inputs": [{"name": "X", "expr_type": cat}],
            "sub_exprs": [f"on_top(X, {src})"]}  # fmt: skip
    goal = {"expr_type": "AND", "sub_exprs": ["not_holding()", nand]}
    text = rng.choice(say.REMOVE).format(obj=cat, src=_look(src))
    return Draft(text, goal, "gen_remove", {"target_receptacle_name": src, "target_object_name": cat})


def two(rng: random.Random, cl: Clutter) -> Draft:
    cats, dst = rng.sample(CATEGORIES, 2), rng.choice(OPEN_AIR_RECEPTACLES)
    for cat in cats:
        cl.add(cat, _elsewhere(rng, dst))
    cl.fill(frozenset(cats))
    text = rng.choice(say.TWO).format(obj=say.a_noun(cats[0]), obj2=say.a_noun(cats[1]), dst=_look(dst))
    goal = _exists([f"on_top(X, {dst})", f"on_top(Y, {dst})", "not_holding()"], *cats)
    return Draft(text, goal, "gen_two", {"target_receptacle_name": dst, "obj1": cats[0], "obj2": cats[1]})


def fridge_door(rng: random.Random, cl: Clutter) -> Draft:
    cl.fill()
    open_now = rng.random() < 0.75
    text = rng.choice(say.CLOSE_FRIDGE if open_now else say.OPEN_FRIDGE)
    goal = {"expr_type": "AND", "sub_exprs": [FRIDGE_STATE[not open_now]]}
    return Draft(text, goal, "gen_fridge", {}, [FRIDGE_STATE[open_now]])


def from_container(rng: random.Random, cl: Clutter) -> Draft:
    cat, src = rng.choice(CATEGORIES), rng.choice((FRIDGE, DRAWER_LEFT, DRAWER_RIGHT))
    dst = rng.choice(OPEN_AIR_RECEPTACLES)
    cl.add(cat, src)
    cl.fill(frozenset({cat}))
    text = rng.choice(say.FROM_CONTAINER).format(obj=cat, src=_look(src), dst=_look(dst))
    entities = {"source_receptacle_name": src, "target_receptacle_name": dst, "target_object_name": cat}
    return Draft(text, _exists([f"on_top(X, {dst})", "not_holding()"], cat), "gen_container", entities)


def walk(rng: random.Random, cl: Clutter) -> Draft:
    dst = rng.choice(OPEN_AIR_RECEPTACLES)
    cl.fill()
    goal = {"expr_type": "AND", "sub_exprs": [f"robot_at({dst})"]}
    return Draft(
        rng.choice(say.WALK).format(dst=_look(dst)), goal, "gen_walk", {"target_receptacle_name": dst}
    )


def conditional(rng: random.Random, cl: Clutter) -> Draft:
    """Which object to move depends on the fridge door; the goal pins the door state it assumed."""
    cats, dst = rng.sample(CATEGORIES, 2), rng.choice(OPEN_AIR_RECEPTACLES)
    for cat in cats:
        cl.add(cat, _elsewhere(rng, dst))
    cl.fill(frozenset(cats))
    open_now = rng.random() < 0.5
    goal = _exists([FRIDGE_STATE[open_now], f"on_top(X, {dst})", "not_holding()"], cats[0 if open_now else 1])
    text = rng.choice(say.CONDITIONAL).format(
        obj=say.a_noun(cats[0]), obj2=say.a_noun(cats[1]), dst=_look(dst)
    )
    entities = {"target_receptacle_name": dst, "obj1": cats[0], "obj2": cats[1]}
    return Draft(text, goal, "gen_conditional", entities, [FRIDGE_STATE[open_now]])


def distractor(rng: random.Random, cl: Clutter) -> Draft:
    draft = move(rng, cl)
    cat, dst = draft.entities["target_object_name"], draft.entities["target_receptacle_name"]
    other, other_at = rng.choice([(c, r) for _, c, r in cl.items if c != cat and r != dst])
    phrase = rng.choice(say.DISTRACTOR)
    draft.instruction = phrase.format(other=say.a_noun(other) if phrase.startswith("There") else other,
                                      other_at=_look(other_at), obj=say.a_noun(cat), dst=_look(dst))  # fmt: skip
    draft.instruct_id = "gen_distractor"
    return draft


def errands(rng: random.Random, cl: Clutter) -> Draft:
    cats = rng.sample(CATEGORIES, 3)
    moves = [tuple(rng.sample(OPEN_AIR_RECEPTACLES, 2)) for _ in cats]
    for cat, (src, _) in zip(cats, moves, strict=True):
        cl.add(cat, src)
    cl.fill(frozenset(cats))
    dsts = [dst for _, dst in moves]
    goal = _exists([*(f"on_top({v}, {d})" for v, d in zip("XYZ", dsts, strict=True)), "not_holding()"], *cats)
    text = rng.choice(say.MULTI).format(obj=cats[0], obj2=cats[1], obj3=cats[2],
                                        dst=_look(dsts[0]), dst2=_look(dsts[1]), dst3=_look(dsts[2]))  # fmt: skip
    entities = {
        **{f"obj{i + 1}": c for i, c in enumerate(cats)},
        **{f"targ_recep{i + 1}": d for i, d in enumerate(dsts)},
    }
    return Draft(text, goal, "gen_multi", entities)


def move_all(rng: random.Random, cl: Clutter) -> Draft:
    cat = rng.choice(CATEGORIES)
    src, dst = rng.sample(OPEN_AIR_RECEPTACLES, 2)
    cl.add(cat, src, copies=rng.randint(2, 3))
    cl.fill(frozenset({cat}))
    goal = {"expr_type": "AND", "quantifier": "FORALL", "inputs": [{"name": "X", "expr_type": cat}],
            "sub_exprs": [f"on_top(X, {dst})", "not_holding()"]}  # fmt: skip
    text = rng.choice(say.MOVE_ALL).format(obj=cat, src=_look(src), dst=_look(dst))
    return Draft(text, goal, "gen_all", {"receptacle1": src, "receptacle2": dst, "object_name": cat})


def _base(rng: random.Random, cl: Clutter) -> Draft:
    family = rng.choice(("move", "move", "remove", "two", "fridge", "container", "walk"))
    if family == "move":
        return move(rng, cl, phrases=rng.choice((say.MOVE, say.MOVE_UNSOURCED)))
    return {"remove": remove, "two": two, "fridge": fridge_door, "container": from_container, "walk": walk}[
        family
    ](rng, cl)


SUBSET_STYLES: dict[str, Callable[[random.Random, Clutter], Draft]] = {
    "base": _base,
    "common_sense": lambda rng, cl: move(rng, cl, say.CATEGORY_HINTS.__getitem__, phrases=say.MOVE_UNSOURCED),
    "complex_instruction": lambda rng, cl: (conditional if rng.random() < 0.5 else distractor)(rng, cl),
    "spatial_relationship": lambda rng, cl: move(
        rng, cl, dst_name=say.RECEPTACLE_SPATIAL.__getitem__, dst_pool=tuple(say.RECEPTACLE_SPATIAL)
    ),
    "visual_appearance": lambda rng, cl: move(
        rng, cl, say.CATEGORY_LOOKS.__getitem__, say.RECEPTACLE_APPEARANCE.__getitem__
    ),
    "long_horizon": lambda rng, cl: (errands if rng.random() < 0.5 else move_all)(rng, cl),
}
