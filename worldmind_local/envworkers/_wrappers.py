"""Env wrappers for measuring and testing the workers themselves (not for evaluation).

`StepLatency` makes a twin step as slowly as a real simulator (a blocking sleep, as an AI2-THOR step
blocks its caller), which is what `scripts/bench_envs.py` measures. `InjectFault` kills or hangs its
worker at a chosen step, once per marker file, to check the failure policy (and a cluster's handling
of dead actors) without a real simulator crash.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path
from typing import Any

from worldmind_local.env import Observation, StepResult, Task

__all__ = ["EnvWrapper", "StepLatency", "InjectFault"]


class EnvWrapper:
    """Forwards the Env seam (and any other attribute) to the wrapped env."""

    def __init__(self, env: Any) -> None:
        self.env = env

    def __getattr__(self, name: str) -> Any:
        if name == "env":  # not set yet (copy, unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.env, name)

    def reset(self, task: Task) -> Observation:
        return self.env.reset(task)

    def step(self, action_id: int) -> StepResult:
        return self.env.step(action_id)

    def close(self) -> None:
        close = getattr(self.env, "close", None)
        if close is not None:
            close()


class StepLatency(EnvWrapper):
    """Adds a fixed blocking delay to every step (and optionally every reset)."""

    def __init__(self, env: Any, step_seconds: float = 0.3, reset_seconds: float = 0.0) -> None:
        super().__init__(env)
        self.step_seconds, self.reset_seconds = step_seconds, reset_seconds

    def reset(self, task: Task) -> Observation:
        if self.reset_seconds:
            time.sleep(self.reset_seconds)
        return self.env.reset(task)

    def step(self, action_id: int) -> StepResult:
        time.sleep(self.step_seconds)
        return self.env.step(action_id)


class InjectFault(EnvWrapper):
    """At step `at_step` of the episode of task `task_id` (any task if None), `kill` the worker process
    (SIGKILL, as the OOM killer would) or `hang` (sleep for an hour). The fault fires once: `marker`
    is created first, and a worker that finds it steps normally (so the restarted one does)."""

    def __init__(self, env: Any, marker: str, at_step: int = 2, fault: str = "kill",
                 task_id: str | None = None) -> None:
        super().__init__(env)
        self.marker, self.at_step, self.fault, self.task_id = Path(marker), at_step, fault, task_id
        self._steps = 0
        self._task: str | None = None

    def reset(self, task: Task) -> Observation:
        self._steps, self._task = 0, task.id
        return self.env.reset(task)

    def step(self, action_id: int) -> StepResult:
        self._steps += 1
        if (self._steps == self.at_step and (self.task_id is None or self._task == self.task_id)
                and not self.marker.exists()):
            self.marker.touch()
            if self.fault == "kill":
                os.kill(os.getpid(), signal.SIGKILL)
            time.sleep(3600)
        return self.env.step(action_id)
