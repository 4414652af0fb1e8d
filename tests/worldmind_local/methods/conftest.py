"""Reuse the agent tests' scripted backend, world and embedder (one definition, loaded by path)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

_path = Path(__file__).resolve().parents[1] / "agent" / "conftest.py"
_spec = importlib.util.spec_from_file_location("_worldmind_agent_test_kit", _path)
assert _spec is not None and _spec.loader is not None
_kit = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = _kit  # dataclasses look their module up there
_spec.loader.exec_module(_kit)

kit = _kit.kit
task = _kit.task
embedder = _kit.embedder
memory = _kit.memory
