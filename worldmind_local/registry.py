"""Registries with lazy targets: nothing heavy is imported until it is asked for.

A target is a string "package.module:Name". `import worldmind_local` therefore works with none of
vllm, torch, ai2thor or habitat installed; asking for a backend that needs them gives an error that
says what to install.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["Registry", "BENCHMARKS", "BACKENDS", "METHODS", "load_target"]


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


BENCHMARKS = Registry("benchmark")
BENCHMARKS.register("eb_alfred", "benchmarks.eb_alfred:ADAPTER")
BENCHMARKS.register("eb_habitat", "benchmarks.eb_habitat:ADAPTER")
BENCHMARKS.register("eb_navigation", "benchmarks.eb_navigation:ADAPTER")

BACKENDS = Registry("backend")
BACKENDS.register("hf", "models.hf_backend:HFBackend")
BACKENDS.register("vllm", "models.vllm_backend:VLLMBackend")
BACKENDS.register("openai", "models.openai_backend:OpenAIBackend")
BACKENDS.register("replay", "models.replay_backend:ReplayBackend")
BACKENDS.register("random", "models.random_backend:RandomBackend")

METHODS = Registry("method")
METHODS.register("worldmind", "worldmind_local.methods.worldmind:WorldMind")
# The paper's ablations as method names (the same switches also exist as `worldmind run` flags).
METHODS.register("worldmind_no_goal", "worldmind_local.methods.worldmind:WorldMindNoGoal")
METHODS.register("worldmind_no_process", "worldmind_local.methods.worldmind:WorldMindNoProcess")
METHODS.register("worldmind_no_verifier", "worldmind_local.methods.worldmind:WorldMindNoVerifier")
METHODS.register("worldmind_baseline", "worldmind_local.methods.worldmind:WorldMindBaseline")
METHODS.register("worldmind_verify_every", "worldmind_local.methods.worldmind:WorldMindVerifyEvery")
