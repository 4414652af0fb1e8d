"""Worked in-context examples for EB-Habitat: oracle plans replayed on the twin, in WorldMind's format.

The official WorldMind configs show the planner 10 worked examples for EB-Habitat, and the paper's
ablation keeps the same examples for every variant. Ours are built, in our own words, from expert
plans run through the twin, never from the episode being evaluated.

Pool. With the data pack: its episodes (`base` first, then the other subsets in EmbodiedBench's
order) with their oracle plans (`Task.expert_plan`, oracle.py), one per starting arrangement
(several subsets reuse one arrangement under another instruction) and one per instruction. Without
it: the generated suite of POOL_SEED, a seed no default evaluation uses (the default suite seed is
0). A plan is kept only if it has at most MAX_ACTIONS actions, runs clean on the twin (no invalid
step) and succeeds with its last action. Order: plans with no skipped prediction first; within that,
goal kinds take turns.

Predictions. `predicted_state` is a short first-person sentence written from the twin's abstract
state after the action (`Observation.text`) about what the action changes; it never names what the
robot could not know yet. Navigation targets are named places whose location the robot knows, so a
navigation is always grounded, even to a receptacle whose contents it has not seen (the prediction
then says where it stands and what it holds, not what lies there); placing and opening or closing a
door act on such places too. A pick is ungrounded when its category was listed in no abstract state
of the example so far. From the first ungrounded action on, every prediction is the skip string (the
cascading rule); oracle plans navigate to an object before picking it, so in practice none skips.

Exclusion. `exclude` holds task ids and instructions of the evaluated episode (compared case-
insensitively, stripped, a trailing '.' ignored). A matching example is dropped, and with the data
pack so is every example with the same starting arrangement; the next one of the pool takes its
place.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from itertools import chain
from pathlib import Path
from typing import Any

from benchmarks.eb_habitat import ADAPTER
from benchmarks.eb_habitat.data import SUBSETS, load_episodes
from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.env import Env, ExampleAction, Task, UnknownActionError, WorkedExample
from worldmind_local.examples import norm, pick, pool_root

__all__ = ["worked_examples", "POOL_SEED", "MAX_ACTIONS"]

POOL_SEED = 10_007  # the generated pool's seed: never the default suite's (0)
POOL_SIZE = 60  # generated tasks replayed for the pool
MAX_ACTIONS = 12
MAX_PREDICTION = 200
_KINDS = ("move_object", "move_objects", "move_objects_conditional", "move_all_objects", "remove_object",
          "articulated_state", "robot_position")  # fmt: skip
_COUNT = re.compile(r" \(x\d+\)$")
_DOOR_STATE = re.compile(r" \((open|closed)\)$")


@dataclass(frozen=True)
class _Candidate:
    example: WorkedExample
    episode: str  # the underlying starting arrangement (or task id for generated tasks)
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
        banned = frozenset(ep for key in excluded for ep in index.get(key, ()))
    return pick(pool, n, excluded, banned)


# -- pools -------------------------------------------------------------------------------------------
def _arrangement(episode: dict[str, Any]) -> str:
    """What makes two episodes the same scene: the scene and where every object starts."""
    return json.dumps([episode.get("scene_id"), sorted(episode.get("name_to_receptacle", {}).items())])


@lru_cache(maxsize=16)
def _data_pool(root: str, subset: str) -> tuple[_Candidate, ...]:
    tasks = ADAPTER.load_tasks(Path(root), subset)
    return _build(tasks, lambda t: _arrangement(t.payload), ADAPTER.make_env("twin", data_dir=root))


@lru_cache(maxsize=1)
def _generated_pool() -> tuple[_Candidate, ...]:
    tasks = ADAPTER.generate_tasks(POOL_SEED, "base", POOL_SIZE)
    return _build(tasks, lambda t: t.id, ADAPTER.make_env("twin"))


@lru_cache(maxsize=4)
def _episode_index(root: str) -> dict[str, frozenset[str]]:
    """Normalised task id and instruction of every data-pack episode -> its starting arrangement(s)."""
    index: dict[str, set[str]] = {}
    for subset in SUBSETS:
        for episode in load_episodes(Path(root), subset):
            for key in (f"eb_habitat/{subset}/{episode['index']}", episode["instruction"]):
                index.setdefault(norm(key), set()).add(_arrangement(episode))
    return {key: frozenset(eps) for key, eps in index.items()}


def _build(tasks: Sequence[Task], episode_of: Callable[[Task], str], env: Env) -> tuple[_Candidate, ...]:
    found: list[_Candidate] = []
    for task in tasks:
        replay = _replay(env, task)
        if replay is None:
            continue
        actions, skip_from = replay
        tier = 0 if skip_from is None else 1 if skip_from else 2
        example = WorkedExample(task.id, task.instruction, _reasoning(task, actions, skip_from),
                                _language_plan(actions), actions)  # fmt: skip
        found.append(_Candidate(example, episode_of(task), task.task_type, tier))
    env.close()
    kinds = _KINDS + tuple(sorted({c.task_type for c in found} - set(_KINDS)))
    out: list[_Candidate] = []
    for tier in (0, 1, 2):  # within a tier goal kinds take turns, each in pool order
        queues = [[c for c in found if c.tier == tier and c.task_type == k] for k in kinds]
        while any(queues):
            out += [q.pop(0) for q in queues if q]
    return tuple(out)


# -- replay ------------------------------------------------------------------------------------------
@dataclass
class _View:
    """The parts of an EB-Habitat abstract state that predictions use."""

    location: str = ""  # "the table 2 (closed)"; "" at the start position
    holding: str = ""
    within: dict[str, list[str]] = field(default_factory=dict)  # receptacle -> categories on it


def _parse(text: str) -> _View:
    view = _View()
    for line in text.splitlines():
        head, _, rest = line.partition(": ")
        rest = rest.rstrip(".")
        if head == "Robot location" and not rest.startswith("the start position"):
            view.location = rest
        elif head == "Holding" and rest != "nothing":
            view.holding = rest
        elif head == "Objects within reach" and rest != "none":
            for part in rest.split("; "):
                recep, _, items = part.partition(": ")
                view.within[recep] = [_COUNT.sub("", c) for c in items.split(", ")]
    return view


def _replay(env: Env, task: Task) -> tuple[tuple[ExampleAction, ...], int | None] | None:
    """The plan's actions with ids, feedback and predictions, and where skipping starts; None unless
    the plan runs clean and succeeds within MAX_ACTIONS."""
    plan = task.expert_plan
    if not plan or len(plan) > MAX_ACTIONS:
        return None
    prev = _parse(env.reset(task).text)
    seen = {c for cats in prev.within.values() for c in cats}
    actions: list[ExampleAction] = []
    skip_from: int | None = None
    for k, name in enumerate(plan):
        if skip_from is None and name.startswith("pick up the ") and name[len("pick up the ") :] not in seen:
            skip_from = k
        try:
            action_id = env.action_id(name)
        except UnknownActionError:
            return None
        result = env.step(action_id)
        if result.invalid:
            return None
        after = _parse(result.observation.text)
        predicted = SKIP_STRING if skip_from is not None else _predict(name, prev, after, result.feedback)
        actions.append(ExampleAction(action_id, name, predicted, result.feedback))
        if result.success:  # only at the last action: an earlier success would leave steps unexplained
            return (tuple(actions), skip_from) if k == len(plan) - 1 else None
        if result.done:
            return None
        prev = after
        seen |= {c for cats in after.within.values() for c in cats}
    return None


# -- predicted states ----------------------------------------------------------------------------------
def _hands(view: _View, still: bool = False) -> str:
    if not view.holding:
        return "my hands are empty"
    return f"I am {'still ' if still else ''}holding the {view.holding}"


def _predict(action: str, prev: _View, after: _View, feedback: str) -> str:
    if action.startswith("navigate to "):
        text = f"I am at {after.location}; {_hands(after, still=bool(prev.holding))}."
    elif action.startswith("pick up the "):
        cat = action[len("pick up the ") :]
        here = _DOOR_STATE.sub("", prev.location)
        sources = [r for r, cats in prev.within.items() if cat in cats]
        source = here if here in sources else sources[0] if sources else ""
        text = f"I am holding the {cat}" + (f", taken from {source}" if source else "") + "."
    elif action.startswith("place at "):
        text = f"The {prev.holding} now lies on {action[len('place at ') :]} and my hands are empty."
    elif " and now " in feedback:  # open / close: "... and now cabinet 5 is open."
        door_state = feedback.split(" and now ", 1)[1].rstrip(".")
        text = f"The {door_state}; {_hands(after)}."
    else:
        text = f"I have done '{action}'; {_hands(after)}."
    return text if len(text) <= MAX_PREDICTION else text[: MAX_PREDICTION - 3].rsplit(" ", 1)[0] + "..."


# -- reasoning and language plan -------------------------------------------------------------------------
def _moves(actions: Sequence[ExampleAction]) -> list[tuple[str, str]]:
    """(category, receptacle) for every pick followed by a place."""
    out, held = [], ""
    for a in actions:
        if a.action_name.startswith("pick up the "):
            held = a.action_name[len("pick up the ") :]
        elif a.action_name.startswith("place at ") and held:
            out.append((held, a.action_name[len("place at ") :]))
            held = ""
    return out


def _reasoning(task: Task, actions: Sequence[ExampleAction], skip_from: int | None) -> str:
    moves = _moves(actions)
    doors = [a.action_name for a in actions if a.action_name.startswith(("open ", "close "))]
    last = actions[-1].action_name
    if task.task_type == "robot_position" or not (moves or doors):
        text = f"Nothing has to be moved here; I only need to end up at {last.removeprefix('navigate to ')}."
    elif task.task_type == "articulated_state" and not moves:
        text = f"Only a door matters for this goal, so I go to it and {doors[-1]}."
    elif task.task_type == "remove_object":
        cat, dest = moves[0]
        text = f"The {cat} must not stay where it is, so I pick it up and leave it on {dest} instead."
    else:
        goal = " and ".join(f"the {c} on {r}" for c, r in moves)
        text = (
            f"The goal is {goal}; I can carry one object at a time, so I go to each, pick it up and place it."
        )
    if doors and moves and doors[0] != last:
        text += f" I also {' and then '.join(doors)} along the way."
    if skip_from is not None:
        text += " I have not seen the object yet, so from that pick on I do not predict the outcome."
    return text


def _phrase(name: str) -> str:
    if name.startswith("navigate to "):
        return "go to " + name[len("navigate to ") :]
    if name.startswith("place at "):
        return "place it at " + name[len("place at ") :]
    return name


def _language_plan(actions: Sequence[ExampleAction]) -> str:
    phrases = [_phrase(a.action_name) for a in actions]
    body = phrases[0] if len(phrases) == 1 else ", ".join(phrases[:-1]) + " and finally " + phrases[-1]
    return f"I will {body}."
