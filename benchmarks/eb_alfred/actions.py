"""EB-ALFRED's action space: the 162 global actions and the per-scene instance actions.

The global list is built exactly as EBAlfEnv.get_global_action_space does (ids 0-161). Per scene,
EmbodiedBench appends instance actions for object types with two or more instances: the first
instance keeps the bare type name, the k-th is called `Type_k`. Receptacle instances (including
movable receptacles such as Bowl or Mug) and other pickupable instances are grouped separately; the
appended actions are `find a Type_k` for the receptacle names, then `open/close the Type_k` for those
whose type is openable, then `find a Type_k` for the pickupable names, each group sorted as strings.

EmbodiedBench walks AI2-THOR's metadata order, which the data pack does not have; we use objects
sorted by objectId as the documented convention (the same order the FloorPlan files list).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from benchmarks.eb_alfred.typefacts import FIND_TYPES, OPEN_TYPES, PICK_TYPES, SLICE_TYPES, TOGGLE_TYPES

__all__ = [
    "GLOBAL_ACTIONS",
    "InstanceNames",
    "instance_names",
    "compile_action",
    "PUT_ACTION",
    "DROP_ACTION",
]

PUT_ACTION = "put down the object in hand"
DROP_ACTION = "drop the object in hand"


def _global_actions() -> tuple[str, ...]:
    actions = [f"find a {t}" for t in FIND_TYPES]
    actions += [f"pick up the {t}" for t in PICK_TYPES]
    actions += [PUT_ACTION, DROP_ACTION]
    for t in OPEN_TYPES:
        actions += [f"open the {t}", f"close the {t}"]
    for t in TOGGLE_TYPES:
        actions += [f"turn on the {t}", f"turn off the {t}"]
    actions += [f"slice the {t}" for t in SLICE_TYPES]
    return tuple(actions)


GLOBAL_ACTIONS: tuple[str, ...] = _global_actions()


@dataclass(frozen=True)
class InstanceNames:
    """EB's name <-> objectId maps for multi-instance types, and the actions they add."""

    name_to_id: dict[str, str]
    id_to_name: dict[str, str]
    extra_actions: tuple[str, ...]

    @property
    def actions(self) -> list[str]:
        return list(GLOBAL_ACTIONS) + list(self.extra_actions)


def _group(pairs: Iterable[tuple[str, str]]) -> dict[str, list[str]]:
    groups: dict[str, list[str]] = {}
    for obj_type, object_id in pairs:
        groups.setdefault(obj_type, []).append(object_id)
    return groups


def instance_names(
    receptacles: Sequence[tuple[str, str]], pickupables: Sequence[tuple[str, str]]
) -> InstanceNames:
    """Apply EB's naming rule to (objectType, objectId) pairs given in metadata order."""
    name_to_id: dict[str, str] = {}
    extra_receptacles: list[str] = []
    extra_pickupables: list[str] = []
    for groups, extras in ((_group(receptacles), extra_receptacles), (_group(pickupables), extra_pickupables)):
        for obj_type, ids in groups.items():
            if len(ids) < 2:
                continue
            for k, object_id in enumerate(ids, start=1):
                name = obj_type if k == 1 else f"{obj_type}_{k}"
                name_to_id[name] = object_id
                if k > 1:
                    extras.append(name)
    recep_names = sorted(set(extra_receptacles))
    pick_names = sorted(set(extra_pickupables))
    extra = [f"find a {n}" for n in recep_names]
    for n in recep_names:
        if n.split("_")[0] in OPEN_TYPES:
            extra += [f"open the {n}", f"close the {n}"]
    extra += [f"find a {n}" for n in pick_names if n.split("_")[0] in PICK_TYPES]
    id_to_name = {object_id: name for name, object_id in name_to_id.items()}
    return InstanceNames(name_to_id, id_to_name, tuple(extra))


def compile_action(action: str, name_to_id: dict[str, str]) -> tuple[str, str]:
    """(verb, argument) of an action string, after EB's name-to-id substitution.

    EB substitutes the last word by its objectId when the action text contains 'find', 'open' or
    'close' (a plain substring test) and the last word is a mapped name; the skill then targets that
    exact instance. The argument is the raw text EB hands to the skill (before natural_word_to_ithor_name).
    """
    text = action
    if "find" in text or "open" in text or "close" in text:
        words = text.split(" ")
        if words[-1] in name_to_id:
            text = " ".join(words[:-1] + [name_to_id[words[-1]]])
    if text.startswith("find "):
        return "find", text.replace("find a ", "").replace("find an ", "")
    if text.startswith("pick up "):
        return "pick", text.replace("pick up the ", "")
    if text.startswith("put down "):
        return "put", ""
    if text.startswith("open "):
        return "open", text.replace("open the ", "")
    if text.startswith("close "):
        return "close", text.replace("close the ", "")
    if text.startswith("turn on "):
        return "turn_on", text.replace("turn on the ", "")
    if text.startswith("turn off "):
        return "turn_off", text.replace("turn off the ", "")
    if text.startswith("slice "):
        return "slice", text.replace("slice the ", "")
    if text.startswith("drop"):
        return "drop", ""
    return "unsupported", ""
