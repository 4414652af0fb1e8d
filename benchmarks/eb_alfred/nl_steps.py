"""EmbodiedBench's informal NL-Steps oracle plans (`nl_steps_<subset>.json`) turned into action names.

The steps are lower-case and loose ('find a sinkbasin', 'pick up a ladle', 'put down the ladle'). Two modes:

**Plain mapping** (`map_nl_steps`): `find a(n) X` -> `find a <Type>` (sink/bathtub basins are found as
`Sink` / `Bathtub`), `pick up a/the X` -> `pick up the <Type>`, any `put down ...` -> `put down the object
in hand`, and open/close/turn on/turn off/slice/drop likewise. For clean tasks the steps leave out the
faucet, and in EmbodiedBench an object only gets clean when the faucet is turned on while it lies in the
sink basin, so `find a Faucet`, `turn on the Faucet`, `turn off the Faucet` follow the put into the sink
(the issue asks for exactly this insertion).

**Intent-preserving translation** (`translate_nl_steps`): the plain mapping plus two more rules of the
same kind, for things the steps leave implicit because they name types, not instances. Each rule reads
only what an EB plan writer has: the plan itself, the task type and the episode's action list.
  - *next instance*: in a pick_two task, a `find a X` for a pickupable type X of which the plan has
    already picked up n objects is the visit for object n+1, so it becomes `find a X_<n+1>` when that
    name is in the action list. EB maps a bare `X` to the first instance of a multi-instance type, so
    the literal step walks back to the object already placed; the `_k` names exist for this purpose.
  - *open before put*: a `put down` into a receptacle whose type is openable (EB's alfred_open_obj)
    and which the plan has not opened (or has closed again) gets `open the R` right after `find a R`,
    R being the very name the find used, so that EB resolves both to the same instance. EB's own
    in-context examples do find -> open -> put, `open` keeps EB's current receptacle, and a put into a
    closed receptacle fails in EB. Nothing is closed that the plan does not close; an opened
    receptacle stays open for later visits (the translation tracks the plan's own open/close steps).
No rule reorders steps, drops steps or picks a destination the plan does not name: a plan that picks
an object it never went to, or puts one down without having gone anywhere, is left as written
(tests/benchmarks/eb_alfred/NL_STEPS_REPORT.md says why).
"""

from __future__ import annotations

import re
from collections.abc import Collection, Sequence
from typing import NamedTuple

from benchmarks.eb_alfred.actions import DROP_ACTION, PUT_ACTION
from benchmarks.eb_alfred.typefacts import FIND_TYPES, OPEN_TYPES, PICK_TYPES, SLICE_TYPES, TOGGLE_TYPES

__all__ = [
    "NLStepError",
    "PlanStep",
    "map_step",
    "map_nl_steps",
    "translate_nl_steps",
    "trace_nl_steps",
    "FAUCET_STEPS",
]

FAUCET_STEPS = ("find a Faucet", "turn on the Faucet", "turn off the Faucet")
PICK_TWO = "pick_two_obj_and_place"
CLEAN = "pick_clean_then_place_in_recep"
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


class PlanStep(NamedTuple):
    """One action of a translated plan and where it came from: 'step' (an NL step, as mapped),
    'faucet', 'next_instance' (an NL find renamed to the next instance) or 'open' (inserted)."""

    action: str
    rule: str


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


def _arg(action: str, verb: str) -> str | None:
    return action[len(verb):] if action.startswith(verb) else None


class _Translator:
    """Walks the mapped steps once, keeping only what the plan itself tells: how many objects of each
    type it has picked up, which receptacles its own steps left open, and EB's current receptacle
    (the last find, kept only by a following put or open)."""

    def __init__(self, task_type: str, action_space: Collection[str] | None) -> None:
        self.task_type = task_type
        self.names = None if action_space is None else frozenset(action_space)
        self.out: list[PlanStep] = []
        self.picked: dict[str, int] = {}
        self.left_open: set[str] = set()
        self.current: str | None = None
        self.at_sink = False

    def add(self, action: str, rule: str) -> None:
        self.out.append(PlanStep(action, rule))
        found = _arg(action, "find a ")
        if found is not None:
            self.current, self.at_sink = found, found == "Sink"
        elif action != PUT_ACTION and _arg(action, "open the ") is None:
            self.current = None
        opened, closed = _arg(action, "open the "), _arg(action, "close the ")
        if opened is not None:
            self.left_open.add(opened)
        if closed is not None:
            self.left_open.discard(closed)
        picked = _arg(action, "pick up the ")
        if picked is not None:
            self.picked[picked] = self.picked.get(picked, 0) + 1

    def next_instance(self, action: str, names: frozenset[str]) -> str | None:
        """`find a X_<n+1>` for a pick_two find of a type X with n objects already picked up."""
        found = _arg(action, "find a ")
        if found is None or self.task_type != PICK_TWO or not self.picked.get(found):
            return None
        renamed = f"find a {found}_{self.picked[found] + 1}"
        return renamed if renamed in names else None

    def opener(self, action: str, names: frozenset[str]) -> str | None:
        """`open the R` for a put into the current receptacle R when R is openable and not left open."""
        r = self.current
        if action != PUT_ACTION or r is None or r in self.left_open or r.split("_")[0] not in OPEN_TYPES:
            return None
        return f"open the {r}" if f"open the {r}" in names else None

    def step(self, action: str) -> None:
        if self.names is not None:
            renamed = self.next_instance(action, self.names)
            if renamed is not None:
                self.add(renamed, "next_instance")
                return
            opener = self.opener(action, self.names)
            if opener is not None:
                self.add(opener, "open")
        sink_put = action == PUT_ACTION and self.at_sink
        self.add(action, "step")
        if sink_put and self.task_type == CLEAN:
            for faucet in FAUCET_STEPS:
                self.add(faucet, "faucet")
            self.at_sink = False


def trace_nl_steps(
    steps: Sequence[str], task_type: str, action_space: Collection[str] | None = None
) -> list[PlanStep]:
    """The plan with each action's origin. Without `action_space` this is the plain mapping; with the
    episode's action names it is the intent-preserving translation (the rules in the module doc)."""
    translator = _Translator(task_type, action_space)
    for step in steps:
        translator.step(map_step(step))
    return translator.out


def map_nl_steps(steps: Sequence[str], task_type: str) -> list[str]:
    """Plain mapping: action names for an NL-Steps plan (with the faucet inserted for clean tasks)."""
    return [s.action for s in trace_nl_steps(steps, task_type)]


def translate_nl_steps(steps: Sequence[str], task_type: str, action_space: Collection[str]) -> list[str]:
    """Intent-preserving translation: the plain mapping plus the next-instance and open-before-put rules."""
    return [s.action for s in trace_nl_steps(steps, task_type, action_space)]
