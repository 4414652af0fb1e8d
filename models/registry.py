"""Registries with lazy targets, and the backend registry: nothing heavy is imported until asked for.

A target is a string "package.module:Name" (as lm-evaluation-harness registers its models). `models/`
owns this module so that it stands on its own: the harness (`worldmind_local.registry`) re-uses the
same `Registry` class for benchmarks and methods, never the other way round.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["Registry", "BACKENDS", "load_target"]


def load_target(target: str) -> Any:
    module_name, _, attr = target.partition(":")
    if not attr:
        raise ValueError(f"registry target {target!r} must look like 'package.module:Name'")
    module = importlib.import_module(module_name)
    try:
        return getattr(module, attr)
    except AttributeError as exc:
        raise ImportError(f"{module_name} has no attribute {attr!r} (registry target {target!r})") from exc


class Registry:
    """name -> lazy target, per kind of thing (benchmark, backend, method)."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self._targets: dict[str, str] = {}
        self._loaded: dict[str, Any] = {}

    def register(self, name: str, target: str) -> None:
        self._targets[name] = target
        self._loaded.pop(name, None)

    def names(self) -> list[str]:
        return sorted(self._targets)

    def __contains__(self, name: object) -> bool:
        return name in self._targets

    def get(self, name: str) -> Any:
        if name not in self._targets:
            known = ", ".join(self.names()) or "none"
            raise KeyError(f"unknown {self.kind} {name!r}; known: {known}")
        if name not in self._loaded:
            self._loaded[name] = load_target(self._targets[name])
        return self._loaded[name]


BACKENDS = Registry("backend")
BACKENDS.register("hf", "models.hf_backend:HFBackend")
BACKENDS.register("vllm", "models.vllm_backend:VLLMBackend")
BACKENDS.register("openai", "models.openai_backend:OpenAIBackend")
BACKENDS.register("replay", "models.replay_backend:ReplayBackend")
BACKENDS.register("random", "models.random_backend:RandomBackend")
