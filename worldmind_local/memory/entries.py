"""One World Knowledge Repository entry: a Process or Goal Experience with its full provenance.

An entry is a record, not a live object: it is frozen, so a repository snapshot (`copy()`) can share
entries with its parent safely. Its `id` is a hash of the partition, the text and the provenance (never
the wall clock), so replaying a run produces the same ids and two runs can be diffed entry by entry.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, model_validator

__all__ = ["Partition", "PARTITIONS", "PROCESS", "GOAL", "ExperienceEntry", "MemoryDataError", "entry_id"]

Partition = Literal["process", "goal"]
PARTITIONS: tuple[str, ...] = get_args(Partition)
PROCESS: Partition = "process"   # W_p: corrective rules from prediction errors
GOAL: Partition = "goal"         # W_g: workflows distilled from successful trajectories

# What makes an entry distinct. Embeddings are derived data and stay out of the id.
_ID_FIELDS = (
    "partition", "text", "instruction", "benchmark", "subset", "episode", "task_id", "step", "action",
    "predicted_state", "actual_state", "judge_reason", "planner_model", "judge_model", "run_id",
)
EMBEDDING_FIELDS = ("key_embedding", "text_embedding")


class MemoryDataError(ValueError):
    """A stored repository is malformed: the message names the place (path or row) and the field."""

    def __init__(self, where: str, field_name: str, problem: str) -> None:
        self.where = where
        self.field = field_name
        super().__init__(f"{where}: field {field_name!r}: {problem}")


def entry_id(fields: dict[str, Any]) -> str:
    """Deterministic id from partition + text + provenance; None and "" hash alike, 0 and None do not."""
    parts = ["" if fields.get(name) is None else str(fields.get(name)) for name in _ID_FIELDS]
    digest = hashlib.sha256(json.dumps(parts, ensure_ascii=False).encode("utf-8")).hexdigest()
    return digest[:20]


class ExperienceEntry(BaseModel):
    """A Process Experience (`text` = corrective rule) or Goal Experience (`text` = workflow).

    `instruction` is the source task's instruction and the retrieval key: entries are found by the
    similarity of the current task's instruction to it. The provenance fields say where the entry came
    from so a published repository can be audited.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    id: str = ""
    partition: Partition
    text: str
    instruction: str
    benchmark: str
    subset: str
    episode: int
    task_id: str
    step: int | None = None
    action: str | None = None
    predicted_state: str | None = None
    actual_state: str | None = None
    judge_reason: str | None = None
    planner_model: str = ""
    judge_model: str = ""
    run_id: str = ""
    key_embedding: list[float] | None = None    # embedding of `instruction` (retrieval)
    text_embedding: list[float] | None = None   # embedding of `text` (near-duplicate check)

    @model_validator(mode="before")
    @classmethod
    def _fill_id(cls, data: Any) -> Any:
        if isinstance(data, dict) and not data.get("id"):
            data = {**data, "id": entry_id(data)}
        return data

    @property
    def embedded(self) -> bool:
        """Both embeddings present: the entry can go straight into `add_embedded`."""
        return self.key_embedding is not None and self.text_embedding is not None

    def without_embeddings(self) -> ExperienceEntry:
        """The same record without its vectors (the repository keeps vectors in matrices, not lists)."""
        if self.key_embedding is None and self.text_embedding is None:
            return self
        return self.model_copy(update={"key_embedding": None, "text_embedding": None})
