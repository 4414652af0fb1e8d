"""Loading and validating EmbodiedBench's EB-ALFRED data pack (`<data_dir>/eb_alfred/`).

Files read: `splits.json` (the six subsets, 50 episodes each, in EB's order), `tasks.json` (one
ALFRED task record per `<task>#<repeat_idx>`) and `scenes/trial_initial_states.json` (the exact
initial facts of each ALFRED trial). A malformed file (not UTF-8, not JSON, a NaN or out-of-range
position) raises TaskDataError naming the file, the record and the field; the parsed pack is cached
per path and modification time.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from benchmarks.eb_alfred.goals import TASK_TYPES
from worldmind_local.data import finite_number, read_json_file
from worldmind_local.env import TaskDataError

__all__ = ["AlfredPack", "load_pack", "pack_dir", "SUBSETS"]

SUBSETS = ("base", "common_sense", "complex_instruction", "spatial", "visual_appearance", "long_horizon")


def pack_dir(data_dir: Path) -> Path:
    return Path(data_dir) / "eb_alfred"


@dataclass(frozen=True)
class AlfredPack:
    root: Path
    splits: dict[str, list[dict[str, Any]]]
    tasks: dict[str, dict[str, Any]]
    trials: dict[str, dict[str, Any]]

    def key(self, subset: str, index: int) -> str:
        entry = self.splits[subset][index]
        return f"{entry['task']}#{entry['repeat_idx']}"


def _read_json(path: Path) -> Any:
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found (the EB-ALFRED data pack layout is described in the README)")
    return read_json_file(path)


def _require(cond: bool, path: Path, field: str, problem: str) -> None:
    if not cond:
        raise TaskDataError(path, field, problem)


def _check_splits(path: Path, data: Any) -> dict[str, list[dict[str, Any]]]:
    _require(isinstance(data, dict), path, "<root>", "must be an object {subset: [episodes]}")
    for subset, entries in data.items():
        _require(isinstance(entries, list), path, subset, "must be a list of episodes")
        for i, e in enumerate(entries):
            where = f"{subset}[{i}]"
            _require(isinstance(e, dict), path, where, "must be an object")
            _require(isinstance(e.get("task"), str) and "/" in e["task"], path, f"{where}.task", "must be '<task>/<trial>'")
            _require(isinstance(e.get("repeat_idx"), int), path, f"{where}.repeat_idx", "must be an integer")
            _require(isinstance(e.get("instruction"), str), path, f"{where}.instruction", "must be a string")
    return data


def check_record(path: Path | str, key: str, rec: Any) -> None:
    """Validate one task record (tasks.json format); generated records go through it too."""
    p = Path(path)
    _require(isinstance(rec, Mapping), p, key, "must be an object")
    _require(rec.get("task_type") in TASK_TYPES, p, f"{key}.task_type", f"must be one of {', '.join(TASK_TYPES)}")
    params = rec.get("pddl_params")
    _require(isinstance(params, Mapping), p, f"{key}.pddl_params", "must be an object")
    for name in ("object_target", "parent_target", "toggle_target", "mrecep_target"):
        _require(isinstance(params.get(name), str), p, f"{key}.pddl_params.{name}", "must be a string")
    _require(isinstance(params.get("object_sliced"), bool), p, f"{key}.pddl_params.object_sliced", "must be a boolean")
    scene = rec.get("scene")
    _require(isinstance(scene, Mapping), p, f"{key}.scene", "must be an object")
    ia = scene.get("init_action")
    _require(isinstance(ia, Mapping), p, f"{key}.scene.init_action", "must have numeric x and z")
    for c in ("x", "z"):
        finite_number(p, f"{key}.scene.init_action.{c}", ia.get(c))
    _require(isinstance(scene.get("object_toggles", []), list), p, f"{key}.scene.object_toggles", "must be a list")
    plan = rec.get("plan")
    _require(isinstance(plan, Mapping) and isinstance(plan.get("high_pddl"), list), p, f"{key}.plan.high_pddl", "must be a list")
    for i, step in enumerate(plan["high_pddl"]):
        pa = step.get("planner_action") if isinstance(step, Mapping) else None
        _require(isinstance(pa, Mapping) and isinstance(pa.get("action"), str), p,
                 f"{key}.plan.high_pddl[{i}].planner_action", "must be an object with an 'action'")


def check_facts(path: Path | str, trial: str, facts: Any) -> None:
    """Validate one trial's scene facts (trial_initial_states.json format)."""
    p = Path(path)
    _require(isinstance(facts, Mapping), p, trial, "must be an object")
    for name in ("receptacles", "objects"):
        table = facts.get(name)
        _require(isinstance(table, Mapping), p, f"{trial}.{name}", "must be an object {objectId: facts}")
        for oid, rec in table.items():
            _require(isinstance(rec, Mapping) and isinstance(rec.get("type"), str), p, f"{trial}.{name}.{oid}.type", "must be a string")
            _require(len(oid.split("|")) >= 4, p, f"{trial}.{name}.{oid}", "objectId must look like 'Type|x|y|z'")
            try:
                finite = all(math.isfinite(float(v)) for v in oid.split("|")[1:4])
            except ValueError:
                finite = False
            _require(finite, p, f"{trial}.{name}.{oid}", "objectId coordinates are not finite numbers")
    for name in ("in_receptacle", "in_receptacle_derived"):
        pairs = facts.get(name, [])
        _require(isinstance(pairs, list) and all(isinstance(x, list) and len(x) == 2 for x in pairs), p,
                 f"{trial}.{name}", "must be a list of [object, receptacle] pairs")


@lru_cache(maxsize=4)
def _load(root: Path, stamp: tuple[float, ...]) -> AlfredPack:
    splits_path, tasks_path = root / "splits.json", root / "tasks.json"
    states_path = root / "scenes" / "trial_initial_states.json"
    splits = _check_splits(splits_path, _read_json(splits_path))
    tasks = _read_json(tasks_path)
    _require(isinstance(tasks, dict), tasks_path, "<root>", "must be an object {key: record}")
    states = _read_json(states_path)
    _require(isinstance(states, dict) and isinstance(states.get("trials"), dict), states_path, "trials", "must be an object")
    return AlfredPack(root, splits, tasks, states["trials"])


def load_pack(data_dir: Path) -> AlfredPack:
    root = pack_dir(data_dir).resolve()
    files = [root / "splits.json", root / "tasks.json", root / "scenes" / "trial_initial_states.json"]
    stamp = tuple(f.stat().st_mtime if f.exists() else -1.0 for f in files)
    return _load(root, stamp)


def episode(pack: AlfredPack, subset: str, index: int) -> tuple[str, dict[str, Any], dict[str, Any], dict[str, Any]]:
    """(key, split entry, task record, scene facts) of one episode, validated."""
    entry = pack.splits[subset][index]
    key = f"{entry['task']}#{entry['repeat_idx']}"
    tasks_path = pack.root / "tasks.json"
    states_path = pack.root / "scenes" / "trial_initial_states.json"
    _require(key in pack.tasks, tasks_path, key, f"missing (needed by splits.json {subset}[{index}])")
    check_record(tasks_path, key, pack.tasks[key])
    trial = entry["task"]
    _require(trial in pack.trials, states_path, f"trials.{trial}", f"missing (needed by {key})")
    check_facts(states_path, f"trials.{trial}", pack.trials[trial])
    return key, entry, pack.tasks[key], pack.trials[trial]
