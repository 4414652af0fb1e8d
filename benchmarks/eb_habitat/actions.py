"""EB-Habitat's 70 high-level skills, in EmbodiedBench's id order.

The list is built in code from the scene facts (so the generated suite works with no data present)
and, when the data pack is there, read from `eb_habitat/action_space.json`; a test checks that the
two agree entry for entry. A skill is its PDDL action (`nav`, `pick_<category>`, `place`,
`open_fridge`, `close_fridge`, `open_cab`, `close_cab`), its arguments, and the text planners see.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from worldmind_local.env import TaskDataError

from .scene import CAB_MARKERS, CATEGORIES, FRIDGE_MARKER, RECEPTACLE_TEXT, RECEPTACLES, STATIC_ENTITIES

__all__ = ["Skill", "embedded_skills", "load_skills", "skills_for", "ACTION_SPACE_FILE"]

ACTION_SPACE_FILE = "action_space.json"
_PDDL_ACTIONS = ("nav", "place", "open_fridge", "close_fridge", "open_cab", "close_cab")


@dataclass(frozen=True, slots=True)
class Skill:
    """One skill: `compact` is EmbodiedBench's `name(args)` string, which its feedback code inspects."""

    id: int
    pddl_action: str
    args: tuple[str, ...]
    text: str

    @property
    def compact(self) -> str:
        return f"{self.pddl_action}({','.join(self.args)})"


def _text(pddl_action: str, arg: str) -> str:
    if pddl_action == "nav":
        return f"navigate to the {RECEPTACLE_TEXT[arg]}"
    if pddl_action == "place":
        return f"place at the {RECEPTACLE_TEXT[arg]}"
    if pddl_action.startswith("pick_"):
        return f"pick up the {pddl_action[5:]}"
    verb = pddl_action.split("_", 1)[0]
    return f"{verb} the refrigerator" if arg == FRIDGE_MARKER else f"{verb} the {RECEPTACLE_TEXT[arg]}"


def embedded_skills() -> tuple[Skill, ...]:
    """The 70 skills from the scene facts: nav x16, pick x33, place x11, fridge open/close, cab open x4, close x4."""
    rows: list[tuple[str, str]] = [("nav", e) for e in STATIC_ENTITIES]
    rows += [(f"pick_{c}", "robot_0") for c in CATEGORIES]
    rows += [("place", r) for r in RECEPTACLES]
    rows += [("open_fridge", FRIDGE_MARKER), ("close_fridge", FRIDGE_MARKER)]
    rows += [("open_cab", m) for m in CAB_MARKERS] + [("close_cab", m) for m in CAB_MARKERS]
    return tuple(Skill(i, a, (arg,), _text(a, arg)) for i, (a, arg) in enumerate(rows))


def load_skills(path: Path) -> tuple[Skill, ...]:
    """Read and validate an action_space.json (ids must run 0..n-1 in order, actions must be known)."""
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise TaskDataError(path, "<file>", f"cannot read JSON: {exc}") from exc
    entries = raw.get("actions") if isinstance(raw, dict) else None
    if not isinstance(entries, list) or not entries:
        raise TaskDataError(path, "actions", "expected a non-empty list of skills")
    skills = []
    for i, entry in enumerate(entries):
        where = f"actions[{i}]"
        if not isinstance(entry, dict):
            raise TaskDataError(path, where, "expected an object with id, pddl_action, args, text")
        if entry.get("id") != i:
            raise TaskDataError(
                path, f"{where}.id", f"expected {i} (ids are list positions), got {entry.get('id')!r}"
            )
        action, args, text = entry.get("pddl_action"), entry.get("args"), entry.get("text")
        if not isinstance(action, str) or not (action in _PDDL_ACTIONS or action[5:] in CATEGORIES):
            raise TaskDataError(path, f"{where}.pddl_action", f"unknown skill {action!r}")
        if not isinstance(args, list) or len(args) != 1 or not isinstance(args[0], str):
            raise TaskDataError(path, f"{where}.args", "expected a list with one entity name")
        if not action.startswith("pick_") and args[0] not in STATIC_ENTITIES:
            raise TaskDataError(path, f"{where}.args", f"unknown entity {args[0]!r}")
        if not isinstance(text, str) or not text:
            raise TaskDataError(path, f"{where}.text", "expected the skill's text")
        skills.append(Skill(i, action, (args[0],), text))
    return tuple(skills)


def skills_for(data_dir: Path | None) -> tuple[Skill, ...]:
    """The data pack's skills when `data_dir/eb_habitat/action_space.json` exists, else the embedded list."""
    if data_dir is not None:
        path = Path(data_dir) / "eb_habitat" / ACTION_SPACE_FILE
        if path.is_file():
            return load_skills(path)
    return embedded_skills()


