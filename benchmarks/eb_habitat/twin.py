"""The EB-Habitat twin: a symbolic simulator with EmbodiedBench's skills, preconditions and feedback.

Semantics (PDDL domain `pddl_domain_replica_cad.yaml` + EBHabEnv, spatial model in ``scene``):

* `nav(X)` is always valid and makes X the robot's place.
* `pick_<c>` needs an empty hand and an object of category c near the robot, not shut inside a
  closed refrigerator or drawer; among several, one on the place itself wins, then list order.
* `place(R)` needs a held object and R within reach (`robot_at(R)`); the object then rests on R
  (EmbodiedBench's PDDL `place` has no door condition, so a closed refrigerator takes it too).
* `pick` leaves out objects inside a closed refrigerator or drawer: EmbodiedBench's PDDL says so for
  the drawers (`in` + `closed_cab`); for the refrigerator we follow the task spec (issue 6).
* `open_*`/`close_*` need the door's marker within reach and the door closed / open.
* An episode ends on success (the goal expression holds), after 30 steps, or at 10 invalid actions.
  `progress` is the fraction of the episode's subgoals reached so far (all predicates of a subgoal
  true at once; once reached it stays counted), and 1.0 on success.

Feedback strings are EmbodiedBench's (verbosity 1), word for word, with the cabinet number as the
data sheet gives it (EBHabEnv's own code takes the second "_"-separated word of the marker name,
which would print "cabinet push"; the data sheet is our interface). The hot path is ints and lists;
observations render lazily from a snapshot.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

from worldmind_local.env import Observation, StepResult, Task, UnknownActionError, lookup_action

from .abstract import render_state, render_text
from .actions import Skill, skills_for
from .predicates import compile_node, ground_expr, ground_pred
from .scene import FRIDGE_MARKER, MARKER_RECEPTACLE, STATIC_ENTITIES, episode_reach
from .world import HOME_IDX, NOWHERE, STATIC_INDEX, Entities, World, reach_index

__all__ = ["HabitatTwin", "OK", "INVALID", "MAX_STEPS", "MAX_INVALID"]

MAX_STEPS = 30
MAX_INVALID = 10
OK = "Last action executed successfully"
INVALID = "Last action is invalid."
_PICK_HOLDING = (
    " Robot cannot pick any object when holding something. Please place the object before picking something."
)
_PICK_FAR = (
    " Robot cannot pick any object that is not near the robot. Navigate to other place to find the object."
)
_PLACE_FAR = (
    " Robot cannot place any object that is not near the robot. Navigate to other place to find the object."
)
_PLACE_EMPTY = (
    " Robot cannot place any object when not holding something. Please pick the object before place it."
)
_OPEN = " Check whether the receptacle is already open or the robot is not near the receptacle."
_CLOSE = " Check whether the receptacle is already closed or the robot is not near the receptacle."
NAV, PICK, PLACE, OPEN, CLOSE = range(5)
_FRIDGE_RESET_OPEN = 1.22  # radians: opened_fridge's threshold in the PDDL domain


def _door_name(skill: Skill) -> str:
    marker = skill.args[0]
    return "refrigerator" if marker == FRIDGE_MARKER else f"cabinet {marker.rsplit('_', 1)[1]}"


def _compile_skill(skill: Skill) -> tuple[int, Any, str, tuple[str, str]]:
    """(kind, argument, feedback when valid, (feedback when invalid: hand empty, hand full))."""
    action = skill.pddl_action
    if action == "nav":
        return NAV, STATIC_INDEX[skill.args[0]], OK + ".", (INVALID, INVALID)
    if action.startswith("pick_"):
        cat = action[5:]
        return PICK, cat, f"{OK} and you are holding {cat}.", (INVALID + _PICK_FAR, INVALID + _PICK_HOLDING)
    if action == "place":
        return (
            PLACE,
            STATIC_INDEX[skill.args[0]],
            OK + " and you are holding nothing.",
            (INVALID + _PLACE_EMPTY, INVALID + _PLACE_FAR),
        )
    kind, verb, state = (OPEN, _OPEN, "open") if action.startswith("open") else (CLOSE, _CLOSE, "closed")
    text = f"{OK} and now {_door_name(skill)} is {state}."
    return kind, STATIC_INDEX[skill.args[0]], text, (INVALID + verb, INVALID + verb)


class HabitatTwin:
    """`Env` for EB-Habitat on the symbolic state (see the module docstring for the rules)."""

    benchmark = "eb_habitat"
    max_steps = MAX_STEPS
    max_invalid: int | None = MAX_INVALID

    def __init__(self, skills: Sequence[Skill] | None = None, *, data_dir: Path | None = None) -> None:
        self._skills = tuple(skills) if skills is not None else skills_for(data_dir)
        self.actions: list[str] = [s.text for s in self._skills]
        self._ids = {name: i for i, name in enumerate(self.actions)}
        self._ops = [_compile_skill(s) for s in self._skills]
        self._task: Task | None = None
        self._done = True

    # -- episode set-up -------------------------------------------------------------------------
    def reset(self, task: Task) -> Observation:
        episode = task.payload
        self._task = task
        self._ents = ents = Entities.from_episode(episode)
        doors = [False] * len(STATIC_ENTITIES)
        fridge_joints = (episode.get("ao_states") or {}).get("fridge_:0000") or {}
        doors[STATIC_INDEX[FRIDGE_MARKER]] = any(
            float(v) > _FRIDGE_RESET_OPEN for v in fridge_joints.values()
        )
        reach, seen = episode_reach(episode)
        near_objs = tuple(frozenset(ents.index[o] for o in seen.get(p, ())) for p in STATIC_ENTITIES)
        self._world = world = World(list(ents.start), doors, reach_index(reach), (*near_objs, frozenset()))
        for text in episode.get("start_preds") or []:
            start = ground_pred(text, ents)
            self._apply_start(start.name, start.args)
        self._goal: Callable[[World], bool] = compile_node(ground_expr(episode["goal_preds"], ents))
        groups = [g for g in (episode.get("subgoals") or []) if g]
        self._subgoals = [tuple(ground_pred(p, ents).test for p in g) for g in groups]
        self._reached = [False] * len(self._subgoals)
        self._steps = self._invalid = 0
        self._done = False
        self._success = self._goal(world)
        self._progress = self._update_progress()
        return self._observe()

    def _apply_start(self, name: str, args: tuple[tuple[str, int], ...]) -> None:
        world = self._world
        if name in ("on_top", "at"):
            world.recep[args[0][1]] = args[1][1]
        elif name == "in":
            world.recep[args[0][1]] = STATIC_INDEX[MARKER_RECEPTACLE[STATIC_ENTITIES[args[1][1]]]]
        else:
            world.door_open[args[0][1]] = name.startswith("opened")

    # -- stepping -------------------------------------------------------------------------------
    def step(self, action_id: int) -> StepResult:
        if self._done:
            raise RuntimeError("the episode is over (or was never reset); call reset(task) first")
        if not 0 <= action_id < len(self._ops):
            raise UnknownActionError(
                f"action id {action_id} is not one of the {len(self._ops)} EB-Habitat skills"
            )
        self._steps += 1
        kind, arg, ok_text, bad_texts = self._ops[action_id]
        world = self._world
        holding = world.held != NOWHERE
        if kind == NAV:
            world.place = arg
            valid = True
        elif kind == PICK:
            obj = NOWHERE if holding else self._pick_target(arg)
            valid = obj != NOWHERE
            if valid:
                world.held, world.recep[obj] = obj, NOWHERE
        elif kind == PLACE:
            valid = holding and arg in world.reach[world.place]
            if valid:
                world.recep[world.held], world.held = arg, NOWHERE
        else:
            valid = arg in world.reach[world.place] and world.door_open[arg] == (kind == CLOSE)
            if valid:
                world.door_open[arg] = kind == OPEN
        if valid:
            feedback = ok_text
            self._success = self._goal(world)
            self._progress = self._update_progress()
        else:
            feedback = bad_texts[holding]
            self._invalid += 1
        end_reason = self._end_reason()
        self._done = end_reason is not None
        return StepResult(
            feedback,
            self._success,
            self._progress,
            not valid,
            self._done,
            self._observe(),
            end_reason,
            {"action": self._skills[action_id].compact, "num_invalid": self._invalid, "step": self._steps},
        )

    def _pick_target(self, category: str) -> int:
        world = self._world
        home = HOME_IDX[world.place]
        fallback = NOWHERE
        for obj in self._ents.by_category.get(category, ()):
            if world.reachable(obj):
                if world.recep[obj] in home:
                    return obj
                if fallback == NOWHERE:
                    fallback = obj
        return fallback

    def _update_progress(self) -> float:
        reached = self._reached
        for i, tests in enumerate(self._subgoals):
            if not reached[i]:
                for test in tests:
                    if not test(self._world):
                        break
                else:
                    reached[i] = True
        if self._success:
            return 1.0
        return sum(reached) / len(reached) if reached else 0.0

    def _end_reason(self) -> str | None:
        if self._success:
            return "success"
        if self._invalid >= MAX_INVALID:
            return "max_invalid"
        if self._steps >= MAX_STEPS:
            return "max_steps"
        return None

    def _observe(self) -> Observation:
        snap = self._world.snapshot()
        reach = self._world.reach
        return Observation(
            partial(render_text, self._ents, reach, snap),
            state=partial(render_state, self._ents, reach, snap),
        )

    # -- lookups ----------------------------------------------------------------------------------
    @property
    def world(self) -> World:
        """The live symbolic state (read it, do not change it): oracles and tests plan against it."""
        return self._world

    @property
    def success(self) -> bool:
        """Whether the goal expression holds now."""
        return self._success

    @property
    def entities(self) -> Entities:
        return self._ents

    @property
    def skills(self) -> tuple[Skill, ...]:
        return self._skills

    def action_id(self, name: str) -> int:
        return lookup_action(self._ids, name, benchmark=self.benchmark, task=self._task)

    def close(self) -> None:
        self._done = True
