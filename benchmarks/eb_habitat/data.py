"""Loading EB-Habitat episodes from the data pack's JSON decode (never the pickles: unpickling runs code).

`data_dir/eb_habitat/<subset>.json` is `{subset, source, n_episodes, episodes: [...]}`. Every episode
is validated on load, down to grounding its start predicates, goal expression and subgoals against
its own objects, so a bad record fails here with the file and the field named, not mid-episode.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from worldmind_local.data import read_json_file
from worldmind_local.env import TaskDataError

from .predicates import PredicateError, ground_expr, ground_pred
from .scene import CATEGORIES, RECEPTACLES
from .world import Entities

__all__ = ["SUBSETS", "subset_path", "load_episodes", "validate_episode", "goal_kind", "START_PREDICATES"]

SUBSETS: tuple[str, ...] = (
    "base",
    "common_sense",
    "complex_instruction",
    "spatial_relationship",
    "visual_appearance",
    "long_horizon",
)
# Predicates an episode may set at reset (EmbodiedBench applies start_preds with set_state).
START_PREDICATES = frozenset(
    {"opened_fridge", "closed_fridge", "opened_cab", "closed_cab", "on_top", "at", "in"}
)


def subset_path(data_dir: Path, subset: str) -> Path:
    return Path(data_dir) / "eb_habitat" / f"{subset}.json"


def load_episodes(data_dir: Path, subset: str) -> list[dict[str, Any]]:
    """The subset's episodes in EmbodiedBench's order, validated. Raises TaskDataError."""
    if subset not in SUBSETS:
        raise ValueError(f"unknown EB-Habitat subset {subset!r}; known: {', '.join(SUBSETS)}")
    path = subset_path(data_dir, subset)
    try:
        raw = read_json_file(path)  # not UTF-8, bad JSON, absurd nesting or numbers: TaskDataError
    except FileNotFoundError as exc:
        raise TaskDataError(
            path, "<file>", "missing (expected the JSON decode of the subset's pickle)"
        ) from exc
    if not isinstance(raw, dict) or not isinstance(raw.get("episodes"), list):
        raise TaskDataError(path, "episodes", "expected an object with an 'episodes' list")
    episodes = raw["episodes"]
    for i, episode in enumerate(episodes):
        validate_episode(episode, path, f"episodes[{i}]", expected_index=i)
    return episodes


def _require(cond: bool, path: Path | str, field: str, problem: str) -> None:
    if not cond:
        raise TaskDataError(path, field, problem)


def _check_objects(episode: Mapping[str, Any], path: Path | str, where: str) -> None:
    objs = episode.get("rigid_objs")
    if not isinstance(objs, list) or not objs:
        raise TaskDataError(path, f"{where}.rigid_objs", "expected a non-empty list")
    seen: set[str] = set()
    for j, obj in enumerate(objs):
        at = f"{where}.rigid_objs[{j}]"
        _require(isinstance(obj, dict), path, at, "expected an object")
        name = obj.get("instance_name")
        _require(
            isinstance(name, str) and name not in seen,
            path,
            f"{at}.instance_name",
            f"missing or repeated: {name!r}",
        )
        seen.add(name)
        _require(
            obj.get("category") in CATEGORIES,
            path,
            f"{at}.category",
            f"unknown category {obj.get('category')!r}",
        )
        recep = obj.get("start_receptacle")
        _require(recep in RECEPTACLES, path, f"{at}.start_receptacle", f"unknown receptacle {recep!r}")
    n2r = episode.get("name_to_receptacle")
    if n2r is not None:
        if not isinstance(n2r, dict):
            raise TaskDataError(path, f"{where}.name_to_receptacle", "expected an object")
        for obj in objs:
            got = n2r.get(obj["instance_name"], obj["start_receptacle"])
            _require(
                got == obj["start_receptacle"],
                path,
                f"{where}.name_to_receptacle",
                f"{obj['instance_name']} starts on {got!r} but rigid_objs says {obj['start_receptacle']!r}",
            )


def _check_predicates(episode: Mapping[str, Any], ents: Entities, path: Path | str, where: str) -> None:
    field = f"{where}.start_preds"
    try:
        starts = episode.get("start_preds") or []
        _require(isinstance(starts, list), path, field, "expected a list of predicate strings")
        for k, text in enumerate(starts):
            field = f"{where}.start_preds[{k}]"
            pred = ground_pred(text, ents)
            _require(pred.name in START_PREDICATES, path, field, f"{pred.name} cannot be set at reset")
        field = f"{where}.goal_preds"
        _require(isinstance(episode.get("goal_preds"), dict), path, field, "expected an expression object")
        ground_expr(episode["goal_preds"], ents)
        field = f"{where}.subgoals"
        subgoals = episode.get("subgoals") or []
        _require(isinstance(subgoals, list), path, field, "expected a list of predicate lists")
        for k, group in enumerate(subgoals):
            field = f"{where}.subgoals[{k}]"
            _require(isinstance(group, list), path, field, "expected a list of predicate strings")
            for text in group:
                ground_pred(text, ents)
    except PredicateError as exc:
        raise TaskDataError(path, field, str(exc)) from exc


def validate_episode(
    episode: Any, path: Path | str, where: str = "episode", *, expected_index: int | None = None
) -> None:
    """Check one episode record; raises TaskDataError naming `path` and the field."""
    _require(isinstance(episode, dict), path, where, "expected an object")
    if expected_index is not None:
        _require(
            episode.get("index") == expected_index,
            path,
            f"{where}.index",
            f"expected {expected_index} (episodes are numbered by position), got {episode.get('index')!r}",
        )
    instruction = episode.get("instruction")
    _require(
        isinstance(instruction, str) and bool(instruction.strip()), path, f"{where}.instruction", "missing"
    )
    _check_objects(episode, path, where)
    _check_predicates(episode, Entities.from_episode(episode), path, where)


def goal_kind(goal: Mapping[str, Any]) -> str:
    """A short task type from the goal's shape (EB-Habitat records carry no task type of their own)."""
    flat: list[str] = []

    def walk(node: Any) -> None:
        if isinstance(node, str):
            flat.append(node.split("(", 1)[0])
        else:
            for sub in node.get("sub_exprs", []):
                walk(sub)

    walk(goal)
    text = json.dumps(goal)
    if '"NAND"' in text or '"NOR"' in text:
        return "remove_object"
    if "on_top" not in flat:
        return "robot_position" if "robot_at" in flat else "articulated_state"
    if goal.get("quantifier") == "FORALL":
        return "move_all_objects"
    if flat.count("on_top") > 1:
        return (
            "move_objects_conditional" if any("fridge" in p or "cab" in p for p in flat) else "move_objects"
        )
    return "move_object"
