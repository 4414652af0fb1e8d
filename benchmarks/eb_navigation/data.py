"""Reading EB-Navigation's task files (`<data_dir>/eb_navigation/<subset>.json`) with validation.

Every record is checked field by field, so a malformed file fails with the file and the field named
(`base.json: field 'tasks[3].agentPose.rotation': ...`), never with a KeyError deep inside the twin.
Numbers must be finite floats; a record's `scene` names a file of the data pack, so it must be a plain
floor-plan name that stays inside the pack (never a path of its own).
Optional extras are read from the same data pack: `eb_alfred/scenes/FloorPlanN.json` holds exact
static objects of the same AI2-THOR floor plans (see geometry.py for how they are used).
"""

from __future__ import annotations

import copy
import math
from functools import lru_cache
from pathlib import Path
from typing import Any

from worldmind_local.data import data_file, finite_number, read_json_file
from worldmind_local.env import TaskDataError

__all__ = [
    "SUBSETS",
    "subset_path",
    "has_any_subset",
    "load_records",
    "load_scene_records",
    "load_alfred_scene",
    "parse_object_id",
]

SUBSETS: tuple[str, ...] = (
    "base",
    "common_sense",
    "complex_instruction",
    "visual_appearance",
    "long_horizon",
)
BENCHMARK_DIR = "eb_navigation"


def subset_path(data_dir: Path, subset: str) -> Path:
    return Path(data_dir) / BENCHMARK_DIR / f"{subset}.json"


def has_any_subset(data_dir: Path) -> bool:
    return any(subset_path(data_dir, s).is_file() for s in SUBSETS)


def _number(path: Path, field: str, value: Any) -> float:
    return finite_number(path, field, value)  # NaN, inf and ints past float range included


def _string(path: Path, field: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise TaskDataError(path, field, f"expected a non-empty string, got {value!r}")
    return value


def _xyz(path: Path, field: str, value: Any) -> None:
    if not isinstance(value, dict):
        raise TaskDataError(path, field, f"expected an object with x, y, z, got {value!r}")
    for axis in ("x", "y", "z"):
        if axis not in value:
            raise TaskDataError(path, f"{field}.{axis}", "missing")
        _number(path, f"{field}.{axis}", value[axis])


def validate_record(path: Path, i: int, rec: Any) -> None:
    """Check one task record; the twin relies on every field checked here."""
    where = f"tasks[{i}]"
    if not isinstance(rec, dict):
        raise TaskDataError(path, where, "expected an object")
    for key in ("targetObjectType", "targetObjectIds", "scene", "instruction"):
        if key not in rec:
            raise TaskDataError(path, f"{where}.{key}", "missing")
        _string(path, f"{where}.{key}", rec[key])
    data_file(path.parent.parent / "eb_alfred" / "scenes", rec["scene"], ".json", path, f"{where}.scene")
    if "target_position" not in rec:
        raise TaskDataError(path, f"{where}.target_position", "missing")
    _xyz(path, f"{where}.target_position", rec["target_position"])
    pose = rec.get("agentPose")
    if not isinstance(pose, dict):
        raise TaskDataError(path, f"{where}.agentPose", "missing or not an object")
    _xyz(path, f"{where}.agentPose.position", pose.get("position"))
    rotation = _number(path, f"{where}.agentPose.rotation", pose.get("rotation"))
    if rotation % 90 != 0:
        raise TaskDataError(
            path, f"{where}.agentPose.rotation", f"{rotation} is not a multiple of 90 (the twin turns in 90s)"
        )
    horizon = _number(path, f"{where}.agentPose.horizon", pose.get("horizon"))
    if horizon % 30 != 0 or not -30 <= horizon <= 60:
        raise TaskDataError(path, f"{where}.agentPose.horizon", f"{horizon} is not one of -30, 0, 30, 60")
    hide = rec.get("object_to_hide", [])
    if not isinstance(hide, list) or not all(isinstance(h, str) for h in hide):
        raise TaskDataError(path, f"{where}.object_to_hide", "expected a list of object ids")
    for k, object_id in enumerate([rec["targetObjectIds"], *hide]):
        field = f"{where}.targetObjectIds" if k == 0 else f"{where}.object_to_hide[{k - 1}]"
        if parse_object_id(object_id) is None:
            raise TaskDataError(path, field, f"{object_id!r} is not an AI2-THOR object id 'Type|x|y|z'")


def parse_object_id(object_id: str) -> tuple[str, float, float, float] | None:
    """`"Bread|+01.30|+00.98|-01.53"` -> ("Bread", 1.30, 0.98, -1.53); None if it is not of that form.

    AI2-THOR object ids carry the object's position, which is how objects named only by id (hidden
    duplicates, the ALFRED scene facts) get a place in the twin's room.
    """
    parts = object_id.split("|")
    if len(parts) < 4 or not parts[0]:
        return None
    try:
        x, y, z = (float(p) for p in parts[1:4])
    except ValueError:
        return None
    if not all(math.isfinite(v) for v in (x, y, z)):
        return None
    return parts[0], x, y, z


def _read_json(path: Path) -> Any:
    return read_json_file(path)


@lru_cache(maxsize=32)
def _load_records_cached(path: Path, mtime_ns: int) -> tuple[dict[str, Any], ...]:
    data = _read_json(path)
    if not isinstance(data, dict) or not isinstance(data.get("tasks"), list):
        raise TaskDataError(path, "tasks", "missing or not a list")
    for i, rec in enumerate(data["tasks"]):
        validate_record(path, i, rec)
    return tuple(data["tasks"])


def load_records(data_dir: Path, subset: str) -> list[dict[str, Any]]:
    """The validated task records of one subset, in EmbodiedBench's order (index = list position)."""
    path = subset_path(data_dir, subset)
    if not path.is_file():
        raise FileNotFoundError(f"no EB-Navigation subset file {path}")
    # Copies: callers put records into Task payloads, and the cache must not see their edits.
    return copy.deepcopy(list(_load_records_cached(path.resolve(), path.stat().st_mtime_ns)))


def load_scene_records(data_dir: Path) -> dict[str, list[dict[str, Any]]]:
    """Every record of every subset file present, grouped by floor plan (the room approximation's input)."""
    grouped: dict[str, list[dict[str, Any]]] = {}
    for subset in SUBSETS:
        if subset_path(data_dir, subset).is_file():
            for rec in load_records(data_dir, subset):
                grouped.setdefault(rec["scene"], []).append(rec)
    return grouped


def load_alfred_scene(data_dir: Path, scene: str) -> dict[str, Any] | None:
    """The EB-ALFRED scene facts of the same floor plan, if the data pack has them (else None).

    Only exact facts are returned: static objects as (objectId, type, x, y, z), positions read from the
    ids, and ALFRED's agent interaction poses as (x, z) (where an agent stood, so known free floor).
    """
    path = data_file(Path(data_dir) / "eb_alfred" / "scenes", scene, ".json", Path(data_dir), "scene")
    if not path.is_file():
        return None
    data = _read_json(path)
    if not isinstance(data, dict):
        raise TaskDataError(path, "<file>", "expected an object")
    ids: list[str] = []
    for key in ("receptacles", "static_objects"):
        block = data.get(key, {})
        if not isinstance(block, dict):
            raise TaskDataError(path, key, "expected an object keyed by objectId")
        ids.extend(block)
    poses = data.get("alfred_layout_receptacle_interaction_poses", {})
    if not isinstance(poses, dict):
        raise TaskDataError(path, "alfred_layout_receptacle_interaction_poses", "expected an object")
    free_points: list[tuple[float, float]] = []
    for object_id, pose in poses.items():
        if not (isinstance(pose, list) and len(pose) >= 2):
            raise TaskDataError(
                path, f"alfred_layout_receptacle_interaction_poses[{object_id!r}]", "bad pose"
            )
        free_points.append((_number(path, object_id, pose[0]), _number(path, object_id, pose[1])))
    objects = []
    for object_id in sorted(set(ids)):
        parsed = parse_object_id(object_id)
        if parsed is not None:
            objects.append((object_id, *parsed))
    return {"objects": objects, "free_points": sorted(set(free_points))}
