"""The abstract state s-bar of an EB-ALFRED step: location, held object, what is visible and its states.

It is what the judge compares a predicted state against, so it says only facts: names are the ones
the action space uses (`Cabinet_3`, `Apple_2`), states are open/closed, on/off, sliced and ALFRED's
heated/cooled/cleaned marks, and receptacles list what is visibly inside them. Scenery nobody can act
on (windows, light switches, stove knobs) is left out.
"""

from __future__ import annotations

from typing import Any

from benchmarks.eb_alfred.world import Snapshot, World

__all__ = ["render_text", "render_state"]


def _interesting(w: World, i: int) -> bool:
    o = w.objs[i]
    return o.receptacle or o.pickupable or o.toggleable or o.openable


def _states(w: World, i: int) -> list[str]:
    o, out = w.objs[i], []
    if o.openable:
        out.append("open" if w.is_open[i] else "closed")
    if o.toggleable:
        out.append("on" if w.is_on[i] else "off")
    for label, marks in (("heated", w.heated), ("cooled", w.cooled), ("cleaned", w.cleaned)):
        if i in marks:
            out.append(label)
    return out


def _visible_set(w: World) -> set[int]:
    carried = set(w.carried())
    return {i for i in range(len(w.objs)) if i not in carried and w.visible(i) and _interesting(w, i)}


def _describe(w: World, i: int, shown: set[int], children: dict[int, list[int]]) -> str:
    parts = list(_states(w, i))
    kids = [k for k in children.get(i, ()) if k in shown]
    if kids:
        parts.append("contains: " + _join(w, kids, shown, children))
    name = w.scene.display[i]
    return f"{name} ({'; '.join(parts)})" if parts else name


def _join(w: World, items: list[int], shown: set[int], children: dict[int, list[int]]) -> str:
    """Describe items in name order; slice pieces of one type with no marks collapse to 'AppleSliced x8'."""
    texts: list[str] = []
    plain_slices: dict[str, int] = {}
    for i in sorted(items, key=lambda k: (w.scene.display[k], k)):
        o = w.objs[i]
        if o.slice_of >= 0 and not _states(w, i) and not children.get(i):
            plain_slices[o.type] = plain_slices.get(o.type, 0) + 1
            continue
        texts.append(_describe(w, i, shown, children))
    texts += [f"{t} x{n}" if n > 1 else t for t, n in sorted(plain_slices.items())]
    return ", ".join(texts)


def _children(w: World, members: set[int]) -> dict[int, list[int]]:
    out: dict[int, list[int]] = {}
    for i in members:
        p = w.parent[i]
        if p >= 0:
            out.setdefault(p, []).append(i)
    return out


def render_text(snap: Snapshot) -> str:
    w = World.from_snapshot(snap)
    shown = _visible_set(w)
    carried = set(w.carried())
    children = _children(w, shown | carried)
    if w.holding >= 0:
        holding = _describe(w, w.holding, carried, children)
    else:
        holding = "nothing"
    top = [i for i in shown if w.parent[i] not in shown]
    seen = _join(w, top, shown, children) if top else "nothing of note"
    return f"Location: {w.location}. Holding: {holding}. Visible: {seen}."


def render_state(snap: Snapshot) -> dict[str, Any]:
    """A JSON-serialisable snapshot for logs and tests."""
    w = World.from_snapshot(snap)
    name = w.scene.display
    visible = []
    for i in sorted(_visible_set(w), key=lambda k: (name[k], k)):
        p = w.parent[i]
        visible.append({"name": name[i], "type": w.objs[i].type, "states": _states(w, i), "in": name[p] if p >= 0 else None})
    return {
        "location": w.location,
        "holding": name[w.holding] if w.holding >= 0 else None,
        "agent": list(w.agent),
        "visible": visible,
        "heated": sorted(name[i] for i in w.heated),
        "cooled": sorted(name[i] for i in w.cooled),
        "cleaned": sorted(name[i] for i in w.cleaned),
    }
