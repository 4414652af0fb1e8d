"""The worker side: one env, built in the worker, answering reset / step / fetch / close.

The same class runs in a spawned process (`_process.py`) and as a Ray actor (`_ray.py`). It keeps the
current episode's observations by step number (reset = 0), so the proxy can fetch a lazy field of
any of them later, and so a replay after a restart rebuilds the same numbering.
"""

from __future__ import annotations

import os
import socket
from typing import Any

from worldmind_local.env import Observation, Task
from worldmind_local.envworkers._base import EnvSpec
from worldmind_local.envworkers._codec import encode_field, encode_step

__all__ = ["EnvHost"]


class EnvHost:
    """Owns one env. Replies are plain data (`_codec.py`); exceptions of the env propagate as they are."""

    def __init__(self, spec: EnvSpec, codec: str = "array") -> None:
        self.env = spec.build()
        self.codec = codec
        self._observations: dict[int, Observation] = {}

    def hello(self) -> dict[str, Any]:
        """What the proxy needs before the first reset, and where the worker runs (for messages)."""
        env = self.env
        return {"benchmark": env.benchmark, "max_steps": env.max_steps, "max_invalid": env.max_invalid,
                "pid": os.getpid(), "host": socket.gethostname()}

    def _observation(self, number: int, obs: Observation, eager: tuple[str, ...]) -> dict[str, Any]:
        self._observations[number] = obs
        return {"n": number, **{name: encode_field(obs, name, self.codec) for name in eager}}

    def reset(self, task: Task, eager: tuple[str, ...]) -> dict[str, Any]:
        obs = self.env.reset(task)
        self._observations = {}
        return {"actions": list(self.env.actions), "obs": self._observation(0, obs, eager),
                "max_steps": self.env.max_steps, "max_invalid": self.env.max_invalid}

    def step(self, action_id: int, eager: tuple[str, ...]) -> dict[str, Any]:
        result = self.env.step(action_id)
        number = max(self._observations, default=0) + 1
        return {**encode_step(result), "obs": self._observation(number, result.observation, eager)}

    def fetch(self, number: int, name: str) -> Any:
        if number not in self._observations:
            raise KeyError(f"observation {number} is not in this worker's current episode")
        return encode_field(self._observations[number], name, self.codec)

    def close(self) -> None:
        self._observations = {}
        close = getattr(self.env, "close", None)
        if close is not None:
            close()
