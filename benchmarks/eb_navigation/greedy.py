"""A greedy EB-Navigation planner that reads only the observation text and the feedback strings.

It is the twin's sanity check (the observation text must be enough to navigate by) and a cheap
baseline. It never looks at the simulator's state: it parses the target's rough distance and bearing
from the text, keeps a dead-reckoned estimate of where the target is (in its own start frame, from its
own actions and whether the feedback says they executed), and each step takes the move that brings it
closest to that estimate, avoiding moves the feedback or the text says are blocked and places it has
already been. With no sighting yet it turns right to look around.
"""

from __future__ import annotations

import math
import re
from collections import Counter

from benchmarks.eb_navigation.actions import (
    LOOK_DOWN,
    MOVE_AHEAD,
    MOVE_BACK,
    MOVE_LEFT,
    MOVE_RIGHT,
    MOVE_STEP,
    ROTATE_RIGHT,
)
from benchmarks.eb_navigation.expert import move_delta

__all__ = ["GreedyNavigator", "parse_observation", "target_type_from_instruction"]

_LINE = re.compile(
    r"^- (?P<type>\w+)(?: \(\d+ in view, nearest\))?: about (?P<d>[\d.]+) m ahead"
    r"(?:, (?P<how>slightly|well) to the (?P<side>left|right))?$"
)
_ANGLE = {None: 0.0, "slightly": 20.0, "well": 40.0}  # middle of each bearing band
_BASE_INSTRUCTION = re.compile(r"navigate to the (\w+) in the room")
_VISIT_PENALTY = 0.3


def parse_observation(text: str) -> dict[str, tuple[float, float]]:
    """Object type -> (distance m, bearing degrees, positive = right) for each object line of the text."""
    seen: dict[str, tuple[float, float]] = {}
    for line in text.splitlines():
        m = _LINE.match(line.strip())
        if m:
            angle = _ANGLE[m["how"]] * (-1.0 if m["side"] == "left" else 1.0)
            seen[m["type"]] = (float(m["d"]), angle)
    return seen


def target_type_from_instruction(instruction: str) -> str | None:
    """The object type named by a base-style instruction ("navigate to the Bread in the room ...")."""
    m = _BASE_INSTRUCTION.search(instruction)
    return m.group(1) if m else None


class GreedyNavigator:
    """Call `act(observation_text, last_feedback)` once per step; it returns an action id."""

    def __init__(self, target_type: str) -> None:
        self.target_type = target_type
        self.cell = (0, 0)  # own frame: start cell, start heading = 0
        self.heading = 0
        self.goal: tuple[float, float] | None = None  # target estimate in own-frame metres
        self.visits: Counter[tuple[int, int]] = Counter({(0, 0): 1})
        self.blocked: set[tuple[tuple[int, int], int, int]] = set()
        self.last_action: int | None = None
        self.turns_without_sighting = 0
        self.looked_down = False

    def _update_pose(self, feedback: str | None) -> None:
        action, self.last_action = self.last_action, None
        if action is None or feedback is None:
            return
        if "is invalid" in feedback:
            if action <= MOVE_LEFT:
                self.blocked.add((self.cell, self.heading, action))
            return
        if action <= MOVE_LEFT:
            di, dj = move_delta(action, self.heading)
            self.cell = (self.cell[0] + di, self.cell[1] + dj)
            self.visits[self.cell] += 1
        elif action == ROTATE_RIGHT:
            self.heading = (self.heading + 1) % 4

    def _see_target(self, distance: float, bearing: float) -> None:
        fi, fj = move_delta(MOVE_AHEAD, self.heading)
        ri, rj = move_delta(MOVE_RIGHT, self.heading)
        ahead, right = distance * math.cos(math.radians(bearing)), distance * math.sin(math.radians(bearing))
        x, z = self.cell[0] * MOVE_STEP, self.cell[1] * MOVE_STEP
        self.goal = (x + ahead * fi + right * ri, z + ahead * fj + right * rj)

    def _best_move(self, forward_blocked: bool) -> int:
        assert self.goal is not None
        best, best_score = MOVE_AHEAD, math.inf
        for action in (MOVE_AHEAD, MOVE_RIGHT, MOVE_LEFT, MOVE_BACK):
            if (self.cell, self.heading, action) in self.blocked or (
                action == MOVE_AHEAD and forward_blocked
            ):
                continue
            di, dj = move_delta(action, self.heading)
            nxt = (self.cell[0] + di, self.cell[1] + dj)
            gap = math.hypot(nxt[0] * MOVE_STEP - self.goal[0], nxt[1] * MOVE_STEP - self.goal[1])
            score = gap + _VISIT_PENALTY * self.visits[nxt]
            if score < best_score:
                best, best_score = action, score
        return best

    def act(self, text: str, feedback: str | None = None) -> int:
        self._update_pose(feedback)
        sighting = parse_observation(text).get(self.target_type)
        if sighting is not None:
            self._see_target(*sighting)
            self.turns_without_sighting = 0
        if self.goal is not None:
            action = self._best_move("moving forward is blocked" in text)
        elif self.turns_without_sighting >= 4 and not self.looked_down:
            action, self.looked_down = LOOK_DOWN, True
        else:
            action = ROTATE_RIGHT
            self.turns_without_sighting += 1
        self.last_action = action
        return action
