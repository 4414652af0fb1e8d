"""Fixtures for the World Knowledge Repository tests: a tiny deterministic embedder and entry builders.

The mechanics tests (dedup boundary, budget, top-k order, batching) need exact, hand-chosen vectors and
must not load a model; `HashEmbedder` maps each text to a fixed pseudo-random unit vector (or to a vector
the test pins), and counts the model calls it receives.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from worldmind_local.memory import Embedder, ExperienceEntry


class HashEmbedder(Embedder):
    """Deterministic 8-dim embedder: text -> seeded unit vector, unless `pinned` says otherwise."""

    model_id = "test/hash-embedder"
    dim = 8

    def __init__(self, pinned: dict[str, np.ndarray] | None = None, **kw: Any) -> None:
        super().__init__(**kw)
        self.pinned = dict(pinned or {})
        self.calls: list[list[str]] = []

    def _embed_uncached(self, texts: list[str]) -> np.ndarray:
        self.calls.append(list(texts))
        out = []
        for text in texts:
            if text in self.pinned:
                vec = np.asarray(self.pinned[text], dtype=np.float32)
            else:
                seed = int(hashlib.sha256(text.encode()).hexdigest()[:12], 16)
                vec = np.random.default_rng(seed).standard_normal(self.dim).astype(np.float32)
            out.append(vec / np.linalg.norm(vec))
        return np.stack(out).astype(np.float32)


def _unit(*values: float, dim: int = 8) -> list[float]:
    vec = np.zeros(dim, dtype=np.float64)
    vec[: len(values)] = values
    return (vec / np.linalg.norm(vec)).tolist()


@pytest.fixture
def unit() -> Callable[..., list[float]]:
    """unit(a, b, ...): a unit vector whose first coordinates are proportional to a, b, ... (rest zero)."""
    return _unit


@pytest.fixture
def at_cosine() -> Callable[[float], list[float]]:
    """at_cosine(c): a unit vector whose cosine to unit(1) is c (exact in float64)."""
    return lambda c: _unit(c, float(np.sqrt(1.0 - c * c)))


@pytest.fixture
def embedder_cls() -> type[HashEmbedder]:
    return HashEmbedder


@pytest.fixture
def embedder() -> HashEmbedder:
    return HashEmbedder()


@pytest.fixture
def make_entry() -> Callable[..., ExperienceEntry]:
    """Build an entry with defaults for the provenance fields; pass key/text vectors to pre-embed it."""
    counter = iter(range(1_000_000))

    def build(partition: str = "process", text: str | None = None, instruction: str = "put apple in fridge",
              key: list[float] | None = None, vec: list[float] | None = None, **kw: Any) -> ExperienceEntry:
        n = next(counter)
        fields: dict[str, Any] = {
            "partition": partition, "text": text if text is not None else f"rule {n}",
            "instruction": instruction, "benchmark": "eb_alfred", "subset": "base", "episode": n,
            "task_id": f"task-{n}", "key_embedding": key, "text_embedding": vec,
        }
        fields.update(kw)
        return ExperienceEntry(**fields)

    return build
