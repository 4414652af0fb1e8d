"""The twin's oracle: a shortest action sequence from a start pose to success.

Breadth-first search over (lattice cell, heading) with the four moves and two turns (tilting the camera
never helps to reach a position). Ties are broken by action id, so the plan is deterministic. It is the
expert plan of generated tasks, and of EmbodiedBench tasks in the twin's approximated room (the data
has no expert plans); it is only as good as that approximation.
"""

from __future__ import annotations

from collections import deque

from benchmarks.eb_navigation.actions import (
    MOVE_AHEAD,
    MOVE_BACK,
    MOVE_LEFT,
    MOVE_RIGHT,
    ROTATE_LEFT,
    ROTATE_RIGHT,
)
from benchmarks.eb_navigation.geometry import Floor, reaches

__all__ = ["HEADING_STEPS", "move_delta", "heading_index", "shortest_plan"]

# Lattice step (di, dj) of MoveAhead for headings 0, 90, 180, 270 degrees (THOR: 0 faces +z, 90 faces +x).
HEADING_STEPS: tuple[tuple[int, int], ...] = ((0, 1), (1, 0), (0, -1), (-1, 0))


def heading_index(rotation: float) -> int:
    """0..3 for a rotation that is a multiple of 90 degrees."""
    return int(round(rotation / 90.0)) % 4


def move_delta(action_id: int, heading: int) -> tuple[int, int]:
    """Lattice step of a move action: ahead/back along the heading, right/left across it."""
    fi, fj = HEADING_STEPS[heading]
    ri, rj = HEADING_STEPS[(heading + 1) % 4]  # the right-hand side is the next heading clockwise
    return {
        MOVE_AHEAD: (fi, fj),
        MOVE_BACK: (-fi, -fj),
        MOVE_RIGHT: (ri, rj),
        MOVE_LEFT: (-ri, -rj),
    }[action_id]


def shortest_plan(
    floor: Floor, heading: int, target: tuple[float, float], max_len: int | None = None
) -> list[int] | None:
    """Action ids from cell (0, 0) facing `heading` to a cell within 1.0 m of `target`; None if none exists
    (or none within `max_len` actions)."""
    start = (0, 0, heading)
    if (0, 0) not in floor.free:
        return None
    parent: dict[tuple[int, int, int], tuple[tuple[int, int, int], int] | None] = {start: None}
    queue = deque([(start, 0)])
    while queue:
        state, depth = queue.popleft()
        i, j, h = state
        if reaches(floor.position(i, j), target):
            plan: list[int] = []
            node = state
            while parent[node] is not None:
                node, action = parent[node]  # type: ignore[misc]
                plan.append(action)
            return plan[::-1]
        if max_len is not None and depth >= max_len:
            continue
        for action in (MOVE_AHEAD, MOVE_BACK, MOVE_RIGHT, MOVE_LEFT, ROTATE_RIGHT, ROTATE_LEFT):
            if action == ROTATE_RIGHT:
                nxt = (i, j, (h + 1) % 4)
            elif action == ROTATE_LEFT:
                nxt = (i, j, (h - 1) % 4)
            else:
                di, dj = move_delta(action, h)
                if (i + di, j + dj) not in floor.free:
                    continue
                nxt = (i + di, j + dj, h)
            if nxt not in parent:
                parent[nxt] = (state, action)
                queue.append((nxt, depth + 1))
    return None
