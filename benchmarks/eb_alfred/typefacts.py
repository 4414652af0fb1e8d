"""Type-level facts of EB-ALFRED (shipped with the package, so the twin works with no data pack).

They live in `alfred_types.json` (package data): EmbodiedBench's six type lists (they define the 162 global
actions), ALFRED's receptacle/object compatibility table, and ALFWorld's object properties per type.
A test checks them against the data pack whenever `../shared/embodiedbench` is present.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

__all__ = [
    "type_facts",
    "FIND_TYPES",
    "PICK_TYPES",
    "OPEN_TYPES",
    "TOGGLE_TYPES",
    "SLICE_TYPES",
    "MOVABLE_RECEPTACLES",
    "KNIFE_TYPES",
    "ithor_name",
]


@cache
def type_facts() -> dict[str, Any]:
    text = resources.files("benchmarks.eb_alfred").joinpath("alfred_types.json").read_text()
    return json.loads(text)


_LISTS = type_facts()["global_action_types"]
FIND_TYPES: tuple[str, ...] = tuple(_LISTS["alfred_objs"])
PICK_TYPES: tuple[str, ...] = tuple(_LISTS["alfred_pick_obj"])
OPEN_TYPES: tuple[str, ...] = tuple(_LISTS["alfred_open_obj"])
TOGGLE_TYPES: tuple[str, ...] = tuple(_LISTS["alfred_toggle_obj"])
SLICE_TYPES: tuple[str, ...] = tuple(_LISTS["alfred_slice_obj"])
MOVABLE_RECEPTACLES: frozenset[str] = frozenset(type_facts()["movable_receptacles"])
# Objects that can cut (AI2-THOR's CanSlice tools); ALFRED checks 'Knife' in the held object's type.
KNIFE_TYPES: frozenset[str] = frozenset({"Knife", "ButterKnife"})


def ithor_name(word: str) -> str:
    """EmbodiedBench's natural_word_to_ithor_name: a name with a digit (an objectId) passes unchanged,
    'CD' stays, anything else goes through `string.capwords` word by word, which lower-cases inner
    capitals ('CounterTop' -> 'Countertop'). The result shows up in EB's feedback strings."""
    if any(ch.isdigit() for ch in word) or word == "CD":
        return word
    return "".join(part[:1].upper() + part[1:].lower() for part in word.split())
