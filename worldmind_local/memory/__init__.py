"""The World Knowledge Repository: Process and Goal Experience, embedded, deduplicated, retrieved, saved.

`WorldKnowledgeRepository` holds the entries; `Embedder` turns text into all-MiniLM-L6-v2 vectors (batched
across every stream of a run); `ExperienceEntry` is one experience with its provenance. A saved repository
is a plain Hugging Face dataset (`datasets.load_from_disk(path)`).
"""

from worldmind_local.memory.embedder import DEFAULT_DIM, DEFAULT_MODEL_ID, Embedder, default_embedder
from worldmind_local.memory.entries import (
    GOAL,
    PARTITIONS,
    PROCESS,
    ExperienceEntry,
    MemoryDataError,
    Partition,
)
from worldmind_local.memory.protocol import Memory
from worldmind_local.memory.repository import WorldKnowledgeRepository
from worldmind_local.memory.store import ExperienceStore, StoredExperience

__all__ = [
    "Memory",
    "DEFAULT_DIM",
    "DEFAULT_MODEL_ID",
    "GOAL",
    "PARTITIONS",
    "PROCESS",
    "Embedder",
    "ExperienceEntry",
    "MemoryDataError",
    "Partition",
    "WorldKnowledgeRepository",
    "ExperienceStore",
    "StoredExperience",
    "default_embedder",
]
