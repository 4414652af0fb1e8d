"""The eight EB-Navigation actions, in EmbodiedBench's id order.

The texts are the names planners choose from (EmbodiedBench's `DISCRETE_SKILLSET`, verbatim); the THOR
action name is what EmbodiedBench's feedback reports (`Last action MoveAhead executed successfully.`).
The list is embedded so the generated suite needs no data; a test checks it against the data pack's
`eb_navigation/action_space.json`, and `load_tasks` refuses a data dir whose copy differs.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from worldmind_local.env import TaskDataError

__all__ = [
    "NavAction",
    "ACTIONS",
    "ACTION_TEXTS",
    "MOVE_STEP",
    "TURN_DEGREES",
    "TILT_DEGREES",
    "MOVE_AHEAD",
    "MOVE_BACK",
    "MOVE_RIGHT",
    "MOVE_LEFT",
    "ROTATE_RIGHT",
    "ROTATE_LEFT",
    "LOOK_UP",
    "LOOK_DOWN",
    "check_action_space_file",
]

MOVE_STEP = 0.25  # metres per move action
TURN_DEGREES = 90
TILT_DEGREES = 30

MOVE_AHEAD, MOVE_BACK, MOVE_RIGHT, MOVE_LEFT, ROTATE_RIGHT, ROTATE_LEFT, LOOK_UP, LOOK_DOWN = range(8)


@dataclass(frozen=True, slots=True)
class NavAction:
    """One discrete action: id, EmbodiedBench's text, and the AI2-THOR call it maps to."""

    id: int
    text: str
    thor_action: str
    params: tuple[tuple[str, float], ...]

    def params_dict(self) -> dict[str, float]:
        return dict(self.params)


ACTIONS: tuple[NavAction, ...] = (
    NavAction(0, "Move forward by 0.25", "MoveAhead", (("moveMagnitude", MOVE_STEP),)),
    NavAction(1, "Move backward by 0.25", "MoveBack", (("moveMagnitude", MOVE_STEP),)),
    NavAction(2, "Move rightward by 0.25", "MoveRight", (("moveMagnitude", MOVE_STEP),)),
    NavAction(3, "Move leftward by 0.25", "MoveLeft", (("moveMagnitude", MOVE_STEP),)),
    NavAction(4, "Rotate to the right by 90 degrees.", "RotateRight", (("degrees", TURN_DEGREES),)),
    NavAction(5, "Rotate to the left by 90 degrees.", "RotateLeft", (("degrees", TURN_DEGREES),)),
    NavAction(6, "Tilt the camera upward by 30 degrees.", "LookUp", (("degrees", TILT_DEGREES),)),
    NavAction(7, "Tilt the camera downward by 30 degrees.", "LookDown", (("degrees", TILT_DEGREES),)),
)

ACTION_TEXTS: tuple[str, ...] = tuple(a.text for a in ACTIONS)


def _as_records() -> list[dict[str, Any]]:
    return [
        {"id": a.id, "text": a.text, "thor_action": a.thor_action, "params": a.params_dict()} for a in ACTIONS
    ]


def check_action_space_file(path: Path) -> None:
    """Raise TaskDataError unless `path` (the data pack's action_space.json) matches the embedded list."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise TaskDataError(path, "<file>", f"not valid JSON ({exc})") from exc
    actions = data.get("actions") if isinstance(data, dict) else None
    if not isinstance(actions, list):
        raise TaskDataError(path, "actions", "missing or not a list")
    expected = _as_records()
    if len(actions) != len(expected):
        raise TaskDataError(path, "actions", f"has {len(actions)} entries, EB-Navigation has {len(expected)}")
    for i, (got, want) in enumerate(zip(actions, expected, strict=True)):
        if not isinstance(got, dict):
            raise TaskDataError(path, f"actions[{i}]", "not an object")
        for key in ("id", "text", "thor_action", "params"):
            if got.get(key) != want[key]:
                raise TaskDataError(
                    path, f"actions[{i}].{key}", f"is {got.get(key)!r}, EB-Navigation has {want[key]!r}"
                )
