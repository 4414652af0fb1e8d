"""Procedurally generated EB-Habitat episodes in the data pack's record format, each with an expert plan.

Task `i` of a (seed, subset) suite is drawn from its own RNG, seeded by the string
`"{seed}/{subset}/{i}"`, so suites are deterministic and a longer suite extends a shorter one. The
apartment is EB-Habitat's (receptacles, markers, categories and assets from ``scene``); clutter is
20-30 objects on the open-air receptacles. Task families follow the six subsets: base (move,
remove, two objects, fridge door, take out of a closed refrigerator or drawer, walk), common_sense
(objects by purpose), complex_instruction (fridge-conditional and distractor instructions),
spatial_relationship (kitchen receptacles by position), visual_appearance (by looks) and
long_horizon (three errands, or every instance of a category). The expert plan is the oracle's;
the families live in ``families``; the subgoals are the twin's states along the plan, written as EmbodiedBench writes them; every task is
checked to succeed under its own plan before it is returned.
"""

from __future__ import annotations

import random
from typing import Any

from worldmind_local.env import Task

from .families import SUBSET_STYLES, Clutter
from .oracle import oracle_plan
from .predicates import ground_pred
from .scene import FRIDGE_MARKER, MARKER_RECORDS, STATIC_ENTITIES
from .twin import HabitatTwin
from .world import NOWHERE

__all__ = ["generate_episodes", "generate_tasks", "record_subgoals"]

SCENES = tuple(
    f"data/replica_cad/configs/scenes/v3_sc3_staging_{i:02d}.scene_instance.json" for i in range(19)
)


def _episode(seed: int, subset: str, index: int) -> tuple[dict[str, Any], tuple[str, ...]]:
    rng = random.Random(f"{seed}/{subset}/{index}")
    clutter = Clutter(rng)
    draft = SUBSET_STYLES[subset](rng, clutter)
    objs = clutter.records()
    record: dict[str, Any] = {
        "index": index,
        "loaded_episode_id": str(index),
        "episode_id": f"gen-{seed}-{subset}-{index}",
        "scene_id": rng.choice(SCENES),
        "instruction": draft.instruction,
        "instruct_id": draft.instruct_id,
        "sampled_entities": draft.entities,
        "start_preds": draft.start_preds,
        "goal_preds": draft.goal,
        "subgoals": [],
        "name_to_receptacle": {o["instance_name"]: o["start_receptacle"] for o in objs},
        "rigid_objs": objs,
        "markers": [dict(m) for m in MARKER_RECORDS],
        "ao_states": {
            "fridge_:0000": {"2": 0.0},
            "kitchen_counter_:0000": {str(k): 0.0 for k in range(1, 8)},
        },
        "start_position": [0, 0, 0],
        "start_rotation": [0, 0, 0, 1],
        "targets": {},
        "target_receptacles": [],
        "goal_receptacles": [],
        "info": {"object_labels": {}},
        "sampler_info": {},
        "other_keys": ["additional_obj_config_paths", "scene_dataset_config"],
    }
    plan = oracle_plan(record)
    if not plan.success:  # the generator only builds solvable tasks; this guards the guarantee
        raise RuntimeError(
            f"generated EB-Habitat task {seed}/{subset}/{index} fails its own plan: {plan.reason}"
        )
    record["subgoals"] = record_subgoals(record, plan.actions)
    return record, plan.actions


def record_subgoals(record: dict[str, Any], actions: tuple[str, ...]) -> list[list[str]]:
    """The twin's state after each step of `actions`, as EmbodiedBench's subgoal predicate lists:
    for every object the plan carries, holding / on_top its final receptacle / near the robot, the
    doors the plan changed, and what is within reach. Repeated states are dropped."""
    twin = HabitatTwin()
    task = Task("gen", "eb_habitat", "gen", 0, "", "", payload=record)
    twin.reset(task)
    start_doors = tuple(twin.world.door_open)
    carried: list[int] = []
    for text in actions:  # dry run: which objects move, and where they end up
        twin.step(twin.action_id(text))
        if twin.world.held != NOWHERE and twin.world.held not in carried:
            carried.append(twin.world.held)
    names, final = twin.entities.names, tuple(twin.world.recep)
    twin.reset(task)
    world = twin.world
    out: list[list[str]] = []
    for text in actions:
        twin.step(twin.action_id(text))
        snap = [
            f"on_top({names[o]},{STATIC_ENTITIES[final[o]]})"
            for o in carried
            if final[o] != NOWHERE
            and ground_pred(f"on_top({names[o]},{STATIC_ENTITIES[final[o]]})", twin.entities).test(world)
        ]
        snap += [f"holding({names[o]})" for o in carried if world.held == o]
        snap += [
            _door_pred(i, world.door_open[i])
            for i, was in enumerate(start_doors)
            if world.door_open[i] != was
        ]
        snap += [f"robot_at({STATIC_ENTITIES[e]})" for e in sorted(world.reach[world.place])]
        snap += [f"robot_at({names[o]})" for o in carried if world.near(o)]
        if not out or snap != out[-1]:
            out.append(snap)
    return out


def _door_pred(marker: int, is_open: bool) -> str:
    name = STATIC_ENTITIES[marker]
    kind = "fridge" if name == FRIDGE_MARKER else "cab"
    return f"{'opened' if is_open else 'closed'}_{kind}({name})"


def generate_episodes(seed: int, subset: str, n: int) -> list[tuple[dict[str, Any], tuple[str, ...]]]:
    """`n` generated (episode record, expert plan) pairs for one subset."""
    if subset not in SUBSET_STYLES:
        raise ValueError(f"unknown EB-Habitat subset {subset!r}; known: {', '.join(SUBSET_STYLES)}")
    return [_episode(seed, subset, i) for i in range(n)]


def generate_tasks(seed: int, subset: str, n: int) -> list[Task]:
    from .data import goal_kind

    return [
        Task(
            id=f"eb_habitat/gen{seed}/{subset}/{record['index']}",
            benchmark="eb_habitat",
            subset=subset,
            index=record["index"],
            instruction=record["instruction"],
            task_type=goal_kind(record["goal_preds"]),
            payload=record,
            expert_plan=plan,
        )
        for record, plan in generate_episodes(seed, subset, n)
    ]
