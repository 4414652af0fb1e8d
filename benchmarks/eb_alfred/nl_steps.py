"""EmbodiedBench's informal NL-Steps oracle plans (`nl_steps_<subset>.json`) mapped to action names.

The steps are lower-case and loose ('find a sinkbasin', 'pick up a ladle', 'put down the ladle'). The
mapping: `find a(n) X` -> `find a <Type>` (sink/bathtub basins are found as `Sink` / `Bathtub`),
`pick up a/the X` -> `pick up the <Type>`, any `put down ...` -> `put down the object in hand`, and
open/close/turn on/turn off/slice/drop likewise. For clean tasks the steps leave out the faucet, and
in EmbodiedBench an object only gets clean when the faucet is turned on while it lies in the sink
basin, so `find a Faucet`, `turn on the Faucet`, `turn off the Faucet` follow the put into the sink.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from benchmarks.eb_alfred.actions import DROP_ACTION, PUT_ACTION
from benchmarks.eb_alfred.typefacts import FIND_TYPES, OPEN_TYPES, PICK_TYPES, SLICE_TYPES, TOGGLE_TYPES

__all__ = ["NLStepError", "map_nl_steps", "FAUCET_STEPS"]

FAUCET_STEPS = ("find a Faucet", "turn on the Faucet", "turn off the Faucet")
_ALIASES = {"sinkbasin": "Sink", "bathtubbasin": "Bathtub"}
_VERBS = (
    (re.compile(r"^find (?:a|an|the) (.+)$"), "find a {}", FIND_TYPES),
    (re.compile(r"^pick up (?:a|an|the) (.+)$"), "pick up the {}", PICK_TYPES),
    (re.compile(r"^open (?:a|an|the) (.+)$"), "open the {}", OPEN_TYPES),
    (re.compile(r"^close (?:a|an|the) (.+)$"), "close the {}", OPEN_TYPES),
    (re.compile(r"^turn on (?:a|an|the) (.+)$"), "turn on the {}", TOGGLE_TYPES),
    (re.compile(r"^turn off (?:a|an|the) (.+)$"), "turn off the {}", TOGGLE_TYPES),
    (re.compile(r"^slice (?:a|an|the) (.+)$"), "slice the {}", SLICE_TYPES),
)


class NLStepError(ValueError):
    """A step that maps to no EB action."""


def _type_name(word: str, allowed: Sequence[str]) -> str | None:
    key = word.replace(" ", "").lower()
    if key in _ALIASES:
        return _ALIASES[key]
    return next((t for t in allowed if t.lower() == key), None)


def map_step(step: str) -> str:
    text = step.strip().rstrip(".")
    low = text.lower()
    if low.startswith("put down") or low.startswith("put "):
        return PUT_ACTION
    if low.startswith("drop"):
        return DROP_ACTION
    for pattern, template, allowed in _VERBS:
        m = pattern.match(low)
        if m:
            name = _type_name(m.group(1), allowed)
            if name is None:
                raise NLStepError(f"no EB action for step {step!r}")
            return template.format(name)
    raise NLStepError(f"unrecognised step {step!r}")


def map_nl_steps(steps: Sequence[str], task_type: str) -> list[str]:
    """Action names for an NL-Steps plan (with the faucet inserted for clean tasks)."""
    out: list[str] = []
    at_sink = False
    for step in steps:
        action = map_step(step)
        out.append(action)
        if action.startswith("find a "):
            at_sink = action == "find a Sink"
        if action == PUT_ACTION and at_sink and task_type == "pick_clean_then_place_in_recep":
            out += FAUCET_STEPS
            at_sink = False
    return out
