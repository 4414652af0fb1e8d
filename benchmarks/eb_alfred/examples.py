"""Worked in-context examples for EB-ALFRED: expert plans replayed on the twin, in WorldMind's format.

The official WorldMind configs show the planner 10 worked examples for EB-ALFRED, and the paper's
ablation keeps the same examples for every variant. Ours are built, in our own words, from expert
plans run through the twin, never from the episode being evaluated.

Pool. With the data pack: its episodes that have an expert plan, `base` first and then the other
subsets in EmbodiedBench's order, one per ALFRED trial (an episode of another subset on the same
trial is the same scene and plan in other words) and one per instruction. Without it: the generated
suite of POOL_SEED, a seed no default evaluation uses (the default suite seed is 0). A plan is kept
only if it has at most MAX_ACTIONS actions, runs clean on the twin (no invalid step) and succeeds
with its last action (a twin success earlier would leave steps the reasoning cannot explain).
Order: plans whose predictions are mostly written (see below) first, then plans that skip early,
then plans that skip from the start; within each tier, task types take turns. The generated rooms
start with nothing in view, so every generated example skips from its first action; with the data
pack, 9 of the 10 `base` examples predict at least their first two actions.

Predictions. `predicted_state` is a short first-person sentence written from the twin's abstract
state after the action (`Observation.state`, the structured form of `Observation.text`), about what
the action changes; it never names what the agent could not know yet (the contents of a receptacle
it has not seen). A `find a X` is ungrounded when X (by its exact instance name; `Sink` also as
`SinkBasin`) was in no abstract state of the example so far; any other action is ungrounded when its
target type is neither visible nor held just before it. From the first ungrounded action on, every
prediction is the skip string (the cascading rule).

Exclusion. `exclude` holds task ids and instructions of the evaluated episode (compared case-
insensitively, stripped, a trailing '.' ignored). A matching example is dropped, and with the data
pack so is every example on the same ALFRED trial; the next one of the pool takes its place.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from itertools import chain
from pathlib import Path
from typing import Any

from benchmarks.eb_alfred import ADAPTER
from benchmarks.eb_alfred.actions import DROP_ACTION, PUT_ACTION
from benchmarks.eb_alfred.data import SUBSETS, load_pack
from benchmarks.eb_alfred.goals import TASK_TYPES
from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.env import Env, ExampleAction, Task, UnknownActionError, WorkedExample
from worldmind_local.examples import norm, pick, pool_root

__all__ = ["worked_examples", "POOL_SEED", "MAX_ACTIONS"]

POOL_SEED = 10_007  # the generated pool's seed: never the default suite's (0)
POOL_SIZE = 120  # generated tasks replayed for the pool
MAX_ACTIONS = 12
MAX_PREDICTION = 200
_CONTAINERS = {"Fridge", "Microwave", "Cabinet", "Drawer", "SinkBasin", "BathtubBasin", "GarbageCan", "Box",
               "Bowl", "Cup", "Mug", "Pot", "Pan", "Safe", "LaundryHamper"}  # fmt: skip
_INSTANCE = re.compile(r"_\d+$")


@dataclass(frozen=True)
class _Candidate:
    example: WorkedExample
    episode: str  # the underlying episode (ALFRED trial, or task id for generated tasks)
    task_type: str
    tier: int


def worked_examples(
    n: int, *, data_dir: Path | None = None, exclude: Collection[str] = ()
) -> list[WorkedExample]:
    """`min(n, pool size)` worked examples, the same for the same arguments (cached)."""
    if n <= 0:
        return []
    return list(_select(pool_root(ADAPTER, data_dir), n, frozenset(norm(x) for x in exclude)))


@lru_cache(maxsize=128)
def _select(root: str | None, n: int, excluded: frozenset[str]) -> tuple[WorkedExample, ...]:
    if root is None:
        pool: Iterable[_Candidate] = _generated_pool()
        banned: frozenset[str] = frozenset()
    else:
        pool = chain.from_iterable(_data_pool(root, s) for s in SUBSETS)
        index = _episode_index(root)
        banned = frozenset(trial for key in excluded for trial in index.get(key, ()))
    return pick(pool, n, excluded, banned)


# -- pools -------------------------------------------------------------------------------------------
@lru_cache(maxsize=16)
def _data_pool(root: str, subset: str) -> tuple[_Candidate, ...]:
    with warnings.catch_warnings():  # tasks without an expert plan are simply not in the pool
        warnings.simplefilter("ignore")
        tasks = ADAPTER.load_tasks(Path(root), subset)
    return _build(tasks, lambda t: t.payload["split"]["task"])


@lru_cache(maxsize=1)
def _generated_pool() -> tuple[_Candidate, ...]:
    return _build(ADAPTER.generate_tasks(POOL_SEED, "base", POOL_SIZE), lambda t: t.id)


@lru_cache(maxsize=4)
def _episode_index(root: str) -> dict[str, frozenset[str]]:
    """Normalised task id and instruction of every data-pack episode -> its ALFRED trial(s)."""
    index: dict[str, set[str]] = {}
    for subset, entries in load_pack(Path(root)).splits.items():
        for i, entry in enumerate(entries):
            for key in (f"eb_alfred/{subset}/{i}", entry["instruction"]):
                index.setdefault(norm(key), set()).add(entry["task"])
    return {key: frozenset(trials) for key, trials in index.items()}


def _build(tasks: Sequence[Task], episode_of: Callable[[Task], str]) -> tuple[_Candidate, ...]:
    env = ADAPTER.make_env("twin")
    found: list[_Candidate] = []
    for task in tasks:
        replay = _replay(env, task)
        if replay is None:
            continue
        actions, skip_from = replay
        predicted = len(actions) if skip_from is None else skip_from
        tier = 0 if 2 * predicted >= len(actions) else 1 if predicted else 2
        example = WorkedExample(task.id, task.instruction, _reasoning(task, actions, skip_from),
                                _language_plan(actions), actions)  # fmt: skip
        found.append(_Candidate(example, episode_of(task), task.task_type, tier))
    env.close()
    return _order(found)


def _order(found: list[_Candidate]) -> tuple[_Candidate, ...]:
    """Tier by tier; within a tier task types take turns (in TASK_TYPES order), each in pool order."""
    out: list[_Candidate] = []
    for tier in (0, 1, 2):
        queues = [[c for c in found if c.tier == tier and c.task_type == t] for t in TASK_TYPES]
        while any(queues):
            out += [q.pop(0) for q in queues if q]
    return tuple(out)


# -- replay ------------------------------------------------------------------------------------------
def _replay(env: Env, task: Task) -> tuple[tuple[ExampleAction, ...], int | None] | None:
    """The plan's actions with ids, feedback and predictions, and where skipping starts; None unless
    the plan runs clean and succeeds within MAX_ACTIONS."""
    plan = task.expert_plan
    if not plan or len(plan) > MAX_ACTIONS:
        return None
    prev = env.reset(task).state
    known = _names(prev)
    actions: list[ExampleAction] = []
    skip_from: int | None = None
    for k, name in enumerate(plan):
        if skip_from is None and not _grounded(name, prev, known):
            skip_from = k
        try:
            action_id = env.action_id(name)
        except UnknownActionError:
            return None
        result = env.step(action_id)
        if result.invalid:
            return None
        after = result.observation.state
        predicted = SKIP_STRING if skip_from is not None else _predict(name, prev, after)
        actions.append(ExampleAction(action_id, name, predicted, result.feedback))
        if result.success:  # only at the last action: an earlier success would leave steps unexplained
            return (tuple(actions), skip_from) if k == len(plan) - 1 else None
        if result.done:
            return None
        prev, known = after, known | _names(after)
    return None


def _names(state: dict[str, Any]) -> set[str]:
    names = {v["name"] for v in state["visible"]}
    if state["holding"]:
        names.add(state["holding"])
    return names


def _type(name: str) -> str:
    return _INSTANCE.sub("", name)


def _grounded(action: str, prev: dict[str, Any], known: set[str]) -> bool:
    verb, target = _split(action)
    if verb == "find":
        return target in known or f"{target}Basin" in known
    if not target:  # put down / drop: about the held object
        return True
    here = {v["type"] for v in prev["visible"]} | {v["name"] for v in prev["visible"]}
    if prev["holding"]:
        here |= {prev["holding"], _type(prev["holding"])}
    return target in here


def _split(action: str) -> tuple[str, str]:
    """(verb, target name) of an EB-ALFRED action; target '' for put down / drop."""
    for prefix, verb in (("find a ", "find"), ("pick up the ", "pick"), ("open the ", "open"),
                         ("close the ", "close"), ("turn on the ", "on"), ("turn off the ", "off"),
                         ("slice the ", "slice")):  # fmt: skip
        if action.startswith(prefix):
            return verb, action[len(prefix) :]
    return ("put" if action == PUT_ACTION else "drop" if action == DROP_ACTION else action), ""


# -- predicted states ----------------------------------------------------------------------------------
def _entry(state: dict[str, Any], name: str) -> dict[str, Any] | None:
    return next((v for v in state["visible"] if v["name"] == name), None)


def _marks(state: dict[str, Any], name: str) -> str:
    marks = [m for m in ("heated", "cooled", "cleaned") if name in state[m]]
    return f" ({', '.join(marks)})" if marks else ""


def _where(recep: str) -> str:
    return f"{'in' if _type(recep) in _CONTAINERS else 'on'} the {recep}"


def _hands(state: dict[str, Any]) -> str:
    held = state["holding"]
    return f"I am holding the {held}{_marks(state, held)}" if held else "my hands are empty"


def _changed(prev: dict[str, Any], after: dict[str, Any]) -> str:
    """Heated / cooled / cleaned marks this action added, as a clause ('' if none)."""
    news = [f"the {name} is now {mark}" for mark in ("heated", "cooled", "cleaned")
            for name in after[mark] if name not in prev[mark]]  # fmt: skip
    return "; " + ", ".join(news) if news else ""


def _predict(action: str, prev: dict[str, Any], after: dict[str, Any]) -> str:
    verb, target = _split(action)
    held_before = prev["holding"]
    if verb == "find":
        entry = _entry(after, target) or _entry(after, f"{target}Basin")
        if entry and entry["in"] and _type(entry["in"]) != _type(target):
            text = f"I am next to the {target}, {_where(entry['in'])}; {_hands(after)}."
        elif entry and entry["states"]:
            text = f"I am at the {target}, which is {' and '.join(entry['states'])}; {_hands(after)}."
        else:
            text = f"I am at the {target}; {_hands(after)}."
    elif verb == "pick":
        held = after["holding"]
        before = _entry(prev, held)
        source = f", taken from {_where(before['in'])[3:]}" if before and before["in"] else ""
        text = f"I am holding the {held}{_marks(after, held)}{source}."
    elif verb == "put":
        entry = _entry(after, held_before)
        spot = f" {_where(entry['in'])}" if entry and entry["in"] else " down"
        text = f"The {held_before} is now{spot} and my hands are empty."
    elif verb == "drop":
        text = f"I have dropped the {held_before}; my hands are empty."
    elif verb in ("open", "close"):
        state = "open" if verb == "open" else "closed"
        text = f"The {target} is {state}{_changed(prev, after)}; {_hands(after)}."
    elif verb in ("on", "off"):
        text = f"The {target} is switched {verb}{_changed(prev, after)}; {_hands(after)}."
    elif verb == "slice":
        text = f"The {target} is cut into slices; {_hands(after)}."
    else:
        text = f"The action '{action}' is done; {_hands(after)}."
    return _clip(text)


def _clip(text: str) -> str:
    if len(text) <= MAX_PREDICTION:
        return text
    return text[: MAX_PREDICTION - 3].rsplit(" ", 1)[0].rstrip(",;") + "..."


# -- reasoning and language plan -------------------------------------------------------------------------
_GOALS = {
    "pick_and_place_simple": "a {obj} has to end up {parent}, so I fetch one and put it there",
    "pick_two_obj_and_place": "two {obj}s have to end up {parent}; I can hold only one thing, so I carry them one at a time",
    "look_at_obj_in_light": "I must hold a {obj} while a {toggle} is switched on, so I pick it up first and then turn on the light",
    "pick_clean_then_place_in_recep": "the {obj} must be rinsed before it goes {parent}: I leave it in the sink basin, run the faucet, and take it back",
    "pick_heat_then_place_in_recep": "the {obj} must be heated before it goes {parent}: I put it in the microwave, run it, and take it back",
    "pick_cool_then_place_in_recep": "the {obj} must be cooled before it goes {parent}: closing it inside the fridge cools it, then I take it back",
    "pick_and_place_with_movable_recep": "the {obj} has to sit in a {mrecep} that ends up {parent}, so I put the {obj} into the {mrecep} and carry the {mrecep} there",
}  # fmt: skip


def _reasoning(task: Task, actions: Sequence[ExampleAction], skip_from: int | None) -> str:
    params = task.payload.get("record", {}).get("pddl_params", {})
    obj, parent = params.get("object_target") or "object", params.get("parent_target") or ""
    goal = _GOALS.get(task.task_type, "I follow the instruction step by step").format(
        obj=obj, parent=_where(parent) if parent else "in place", toggle=params.get("toggle_target") or "lamp",
        mrecep=params.get("mrecep_target") or "container")  # fmt: skip
    text = goal[0].upper() + goal[1:] + "."
    if params.get("object_sliced"):
        text += " It also has to be sliced, so I cut it with the knife first."
    if skip_from is not None:
        target = _split(actions[skip_from].action_name)[1] or "my target"
        text += f" I have not seen the {target} yet, so from that search on I do not predict the outcome."
    return text


_PHRASES = {"find": "go to the {t}", "pick": "pick up the {t}", "put": "put it down", "drop": "drop it",
            "open": "open the {t}", "close": "close the {t}", "on": "turn on the {t}",
            "off": "turn off the {t}", "slice": "slice the {t}"}  # fmt: skip


def _language_plan(actions: Sequence[ExampleAction]) -> str:
    phrases = [
        _PHRASES.get(v, a.action_name).format(t=t) for a in actions for v, t in [_split(a.action_name)]
    ]
    body = phrases[0] if len(phrases) == 1 else ", ".join(phrases[:-1]) + " and finally " + phrases[-1]
    return f"I will {body}."
