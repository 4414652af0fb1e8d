"""ExperienceEntry: deterministic ids from content + provenance, immutability, strict fields."""

from __future__ import annotations

import pydantic
import pytest

from worldmind_local.memory import ExperienceEntry
from worldmind_local.memory.entries import entry_id

BASE = {"partition": "process", "text": "Navigate to the fridge before opening it.",
        "instruction": "Put an apple in the fridge.", "benchmark": "eb_alfred", "subset": "base",
        "episode": 3, "task_id": "base-3", "step": 2, "action": "open the Fridge"}


def test_id_is_deterministic_and_ignores_embeddings() -> None:
    a = ExperienceEntry(**BASE)
    b = ExperienceEntry(**BASE, key_embedding=[1.0, 0.0], text_embedding=[0.0, 1.0])
    assert a.id == b.id == entry_id(BASE)
    assert len(a.id) == 20


@pytest.mark.parametrize("field,value", [
    ("partition", "goal"), ("text", "Another rule."), ("episode", 4), ("step", None), ("step", 0),
    ("run_id", "run-b"), ("planner_model", "hf:smollm2"),
])
def test_id_changes_with_content_or_provenance(field: str, value: object) -> None:
    assert ExperienceEntry(**{**BASE, field: value}).id != ExperienceEntry(**BASE).id


def test_explicit_id_kept_and_round_trips_through_json() -> None:
    e = ExperienceEntry(**BASE, id="custom")
    assert e.id == "custom"
    again = ExperienceEntry.model_validate_json(ExperienceEntry(**BASE).model_dump_json())
    assert again == ExperienceEntry(**BASE)


def test_entries_are_frozen_and_strict() -> None:
    e = ExperienceEntry(**BASE)
    with pytest.raises(pydantic.ValidationError):
        e.text = "changed"  # type: ignore[misc]
    with pytest.raises(pydantic.ValidationError):
        ExperienceEntry(**BASE, typo_field=1)
    with pytest.raises(pydantic.ValidationError):
        ExperienceEntry(**{**BASE, "partition": "episodic"})


def test_without_embeddings() -> None:
    e = ExperienceEntry(**BASE, key_embedding=[1.0], text_embedding=[1.0])
    assert e.embedded
    bare = e.without_embeddings()
    assert bare.key_embedding is None and bare.text_embedding is None and bare.id == e.id
    assert not bare.embedded
