"""Worked in-context examples for EB-Navigation: shortest plans replayed on the twin, in WorldMind's format.

The official WorldMind configs show the planner 3 worked examples for EB-Navigation, and the paper's
ablation keeps the same examples for every variant. Ours are built, in our own words, from expert
plans run through the twin, never from the episode being evaluated.

Pool. With the data pack: its episodes (`base` first, then the other subsets present, in
EmbodiedBench's order) with the twin's shortest plans (`Task.expert_plan`, expert.py; EmbodiedBench
ships none for navigation), one per episode (four subsets reuse each base episode under another
instruction) and one per instruction (one target type per example). Without it: the generated suite
of POOL_SEED, a seed no default evaluation uses (the default suite seed is 0). A plan is kept only if
it has at most MAX_ACTIONS actions, runs clean on the twin and reaches the target with its last
action. Order: plans with no skipped prediction first; among those, plans of at most SHORT actions
that use more than one kind of action, then other plans of at most SHORT actions, then the rest;
within each group room types take turns.

Predictions. `predicted_state` is a short first-person sentence written from the twin's abstract
state after the action (`Observation.text`, the objects in view with distance and bearing): how the
pose changed and where the target now appears. An action is ungrounded while the target type has
been in view in no observation of the example so far; from the first ungrounded action on, every
prediction is the skip string (the cascading rule).

Exclusion. `exclude` holds task ids and instructions of the evaluated episode (compared case-
insensitively, stripped, a trailing '.' ignored). A matching example is dropped, and with the data
pack so is every example of the same episode (same room, start pose and target) in any subset; the
next one of the pool takes its place. EB-Navigation instructions name only the target type, so an
evaluated episode also removes every example with the same target type.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Iterable, Sequence
from dataclasses import dataclass
from functools import lru_cache
from itertools import chain, groupby
from pathlib import Path
from typing import Any

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation.data import SUBSETS, load_records, subset_path
from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.env import Env, ExampleAction, Task, UnknownActionError, WorkedExample
from worldmind_local.examples import norm, pick, pool_root

__all__ = ["worked_examples", "POOL_SEED", "MAX_ACTIONS"]

POOL_SEED = 10_007  # the generated pool's seed: never the default suite's (0)
POOL_SIZE = 60  # generated tasks replayed for the pool
MAX_ACTIONS = 10
SHORT = 8  # plans up to this length come first
MAX_PREDICTION = 200
_ROOMS = ("kitchen", "living_room", "bedroom", "bathroom")
_MOVES = ("I moved 0.25 m forward", "I moved 0.25 m back", "I moved 0.25 m to the right",
          "I moved 0.25 m to the left", "I turned 90 degrees to the right", "I turned 90 degrees to the left",
          "I tilted the camera 30 degrees up", "I tilted the camera 30 degrees down")  # fmt: skip
_PHRASES = ("move forward", "move back", "move right", "move left", "rotate right", "rotate left",
            "tilt the camera up", "tilt the camera down")  # fmt: skip


@dataclass(frozen=True)
class _Candidate:
    example: WorkedExample
    episode: str  # the underlying episode (room, start pose, target), or task id for generated tasks
    task_type: str
    rank: int  # lower first: no skip before early skip before all skipped; short and varied first


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
        present = [s for s in SUBSETS if subset_path(Path(root), s).is_file()]
        pool = chain.from_iterable(_data_pool(root, s) for s in present)
        index = _episode_index(root)
        banned = frozenset(ep for key in excluded for ep in index.get(key, ()))
    return pick(pool, n, excluded, banned)


# -- pools -------------------------------------------------------------------------------------------
def _episode_of(record: dict[str, Any]) -> str:
    """What makes two records the same episode: the room, the start pose and the target position."""
    return json.dumps(
        [record.get("scene"), record.get("agentPose"), record.get("target_position")], sort_keys=True
    )


@lru_cache(maxsize=16)
def _data_pool(root: str, subset: str) -> tuple[_Candidate, ...]:
    tasks = ADAPTER.load_tasks(Path(root), subset)
    return _build(tasks, lambda t: _episode_of(t.payload["record"]))


@lru_cache(maxsize=1)
def _generated_pool() -> tuple[_Candidate, ...]:
    return _build(ADAPTER.generate_tasks(POOL_SEED, "base", POOL_SIZE), lambda t: t.id)


@lru_cache(maxsize=4)
def _episode_index(root: str) -> dict[str, frozenset[str]]:
    """Normalised task id and instruction of every data-pack episode -> its episode key(s)."""
    index: dict[str, set[str]] = {}
    for subset in SUBSETS:
        if not subset_path(Path(root), subset).is_file():
            continue
        for i, record in enumerate(load_records(Path(root), subset)):
            for key in (f"eb_navigation/{subset}/{i}", record["instruction"]):
                index.setdefault(norm(key), set()).add(_episode_of(record))
    return {key: frozenset(eps) for key, eps in index.items()}


def _build(tasks: Sequence[Task], episode_of: Callable[[Task], str]) -> tuple[_Candidate, ...]:
    env = ADAPTER.make_env("twin", images=False)
    found: list[_Candidate] = []
    for task in tasks:
        replay = _replay(env, task)
        if replay is None:
            continue
        actions, skip_from, first_view = replay
        skip_tier = 0 if skip_from is None else 1 if skip_from else 2
        example = WorkedExample(task.id, task.instruction, _reasoning(_target(task), first_view),
                                _language_plan(actions), actions)  # fmt: skip
        found.append(_Candidate(example, episode_of(task), task.task_type, 3 * skip_tier + _shape(actions)))
    env.close()
    rooms = _ROOMS + tuple(sorted({c.task_type for c in found} - set(_ROOMS)))
    out: list[_Candidate] = []
    for rank in sorted({c.rank for c in found}):  # within a rank room types take turns, each in pool order
        queues = [[c for c in found if c.rank == rank and c.task_type == r] for r in rooms]
        while any(queues):
            out += [q.pop(0) for q in queues if q]
    return tuple(out)


def _shape(actions: Sequence[ExampleAction]) -> int:
    """0: short and more than one kind of action; 1: short; 2: longer than SHORT."""
    if len(actions) > SHORT:
        return 2
    return 0 if len({a.action_id for a in actions}) > 1 else 1


# -- replay ------------------------------------------------------------------------------------------
def _target(task: Task) -> str:
    return str(task.payload["record"]["targetObjectType"])


def _sighting(text: str, target: str) -> str | None:
    """'about 2.5 m ahead, slightly to the right' for the target's line in an observation, else None."""
    for line in text.splitlines():
        for head in (f"- {target}: ", f"- {target} ("):
            if line.startswith(head):
                return line.split(": ", 1)[1]
    return None


def _replay(env: Env, task: Task) -> tuple[tuple[ExampleAction, ...], int | None, str | None] | None:
    """The plan's actions with ids, feedback and predictions, where skipping starts, and the target's
    sighting at the start; None unless the plan runs clean and succeeds within MAX_ACTIONS."""
    plan = task.expert_plan
    if not plan or len(plan) > MAX_ACTIONS:
        return None
    target = _target(task)
    first_view = _sighting(env.reset(task).text, target)
    seen = first_view is not None
    actions: list[ExampleAction] = []
    skip_from: int | None = None
    for k, name in enumerate(plan):
        if skip_from is None and not seen:
            skip_from = k
        try:
            action_id = env.action_id(name)
        except UnknownActionError:
            return None
        result = env.step(action_id)
        if result.invalid:
            return None
        view = _sighting(result.observation.text, target)
        predicted = SKIP_STRING if skip_from is not None else _predict(action_id, target, view)
        actions.append(ExampleAction(action_id, name, predicted, result.feedback))
        if result.success:  # only at the last action: an earlier success would leave steps unexplained
            return (tuple(actions), skip_from, first_view) if k == len(plan) - 1 else None
        if result.done:
            return None
        seen = seen or view is not None
    return None


def _predict(action_id: int, target: str, view: str | None) -> str:
    where = f"the {target} is {view}" if view else f"the {target} is out of view now"
    text = f"{_MOVES[action_id]}; {where}."
    return text if len(text) <= MAX_PREDICTION else text[: MAX_PREDICTION - 3].rsplit(" ", 1)[0] + "..."


# -- reasoning and language plan -------------------------------------------------------------------------
def _reasoning(target: str, first_view: str | None) -> str:
    if first_view is None:
        return f"I cannot see the {target} yet, so I turn and move to look for it before predicting anything."
    return (f"The {target} is in view, {first_view}, so I move toward it step by step until I am within "
            f"about one meter of it.")  # fmt: skip


def _language_plan(actions: Sequence[ExampleAction]) -> str:
    runs = [(action_id, len(list(group))) for action_id, group in groupby(a.action_id for a in actions)]
    parts = [f"{_PHRASES[a]} {'once' if k == 1 else 'twice' if k == 2 else f'{k} times'}" for a, k in runs]
    body = parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and then " + parts[-1]
    return f"I will {body}."
