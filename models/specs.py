"""Model specs: `models/specs/*.yaml`, addressed as `backend:name` (e.g. `hf:smollm2-135m-instruct`).

A spec names the weights (a local path, a package that ships them, or a builder that makes them in
code), the backend, dtype, context length, chat-template options, default sampling and the roles the
model may play. `make_backend("hf:smollm2-135m-instruct")` is the one way the rest of the suite gets
a `ChatBackend`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from models.base import ROLES, ChatBackend

__all__ = ["ModelSpec", "SPEC_DIR", "list_specs", "load_spec", "make_backend", "set_offline_env"]

SPEC_DIR = Path(__file__).parent / "specs"
USER_SPEC_ENV = "WORLDMIND_MODEL_SPECS"  # extra folders of specs, os.pathsep-separated


def set_offline_env() -> None:
    """Air-gapped by construction: no hub client in this process may go to the network."""
    for var in ("HF_HUB_OFFLINE", "TRANSFORMERS_OFFLINE", "HF_DATASETS_OFFLINE"):
        os.environ[var] = "1"
    os.environ.setdefault("HF_HUB_DISABLE_TELEMETRY", "1")
    os.environ.setdefault("TOKENIZERS_PARALLELISM", "false")


class WeightsSource(BaseModel):
    """Exactly one of path / package / builder.

    - path: a local folder (or file) with the weights; `${VAR}` and `~` are expanded.
    - package: a pip package that ships the weights (optionally `file` inside it, e.g. a GGUF).
    - builder: "module:function" that builds the model in code into a cache folder (tiny test models).
    """

    model_config = ConfigDict(extra="forbid")
    path: str | None = None
    package: str | None = None
    file: str | None = None
    builder: str | None = None
    tokenizer: str | None = None  # optional separate tokenizer source (path or package)


class ModelSpec(BaseModel):
    model_config = ConfigDict(extra="forbid", protected_namespaces=())

    name: str
    backend: str
    description: str = ""
    model_id: str  # the canonical id recorded in manifests and cache keys
    weights: WeightsSource
    dtype: str = "bfloat16"
    context_length: int = 4096
    vision: bool = False
    chat_template_kwargs: dict[str, Any] = Field(default_factory=dict)
    sampling: dict[str, Any] = Field(default_factory=dict)  # defaults for Sampling fields
    roles: list[str] = Field(default_factory=lambda: list(ROLES))
    options: dict[str, Any] = Field(default_factory=dict)  # backend-specific (gpu_memory_utilization, ...)
    source_file: str | None = None

    @property
    def address(self) -> str:
        return f"{self.backend}:{self.name}"


def _spec_dirs() -> list[Path]:
    dirs = [SPEC_DIR]
    extra = os.environ.get(USER_SPEC_ENV, "")
    dirs += [Path(p).expanduser() for p in extra.split(os.pathsep) if p]
    return dirs


def _read_spec_file(path: Path) -> list[ModelSpec]:
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML: {exc}") from exc
    docs = raw if isinstance(raw, list) else [raw]
    specs = []
    for i, doc in enumerate(docs):
        if not isinstance(doc, dict):
            raise ValueError(f"{path}: entry {i} is not a mapping")
        try:
            specs.append(ModelSpec(**doc, source_file=str(path)))
        except ValidationError as exc:
            raise ValueError(f"{path}: entry {i}: {exc}") from exc
        if specs[-1].roles and not set(specs[-1].roles) <= set(ROLES):
            raise ValueError(f"{path}: entry {i}: unknown role in {specs[-1].roles}; known: {ROLES}")
    return specs


def list_specs() -> list[ModelSpec]:
    specs: dict[str, ModelSpec] = {}
    for folder in _spec_dirs():
        if not folder.is_dir():
            continue
        for path in sorted(folder.glob("*.yaml")):
            for spec in _read_spec_file(path):
                specs[spec.address] = spec
    return sorted(specs.values(), key=lambda s: s.address)


def load_spec(address: str) -> ModelSpec:
    """`backend:name`, or a path to a YAML spec file."""
    if address.endswith((".yaml", ".yml")) and Path(address).is_file():
        return _read_spec_file(Path(address))[0]
    if ":" not in address:
        raise KeyError(f"model spec {address!r} must be 'backend:name' (see `worldmind models list`)")
    known = {s.address: s for s in list_specs()}
    if address not in known:
        raise KeyError(
            f"unknown model spec {address!r}; known: {', '.join(sorted(known)) or 'none'}"
        )
    return known[address]


def make_backend(spec: str | ModelSpec, **options: Any) -> ChatBackend:
    """Build the backend a spec names. Imports the backend's heavy libraries only now.

    `replay`, `replay:<spec address>` and `replay:<model id>` (with `cache=PATH`) build a replay backend
    over a recorded response cache; see models/replay_backend.py.
    """
    from models.registry import BACKENDS

    set_offline_env()
    if isinstance(spec, str) and (spec == "replay" or spec.startswith("replay:")):
        # replay needs no spec: `replay`, `replay:<spec address>` or `replay:<model id>` + cache=PATH
        from models.replay_backend import make_replay

        return make_replay(spec, **options)
    if isinstance(spec, str):
        spec = load_spec(spec)
    backend_cls = BACKENDS.get(spec.backend)
    return backend_cls(spec, **options)
