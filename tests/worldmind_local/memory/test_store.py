"""ExperienceStore: the baselines' memory (rows, instruction-key retrieval, budget, snapshots, saving)."""

from __future__ import annotations

import asyncio
from typing import Any

import numpy as np
import pytest

from worldmind_local.memory import ExperienceStore, Memory, StoredExperience
from worldmind_local.memory.store import normalize_instruction


def _entry(n: int, instruction: str = "put apple in fridge", *, kind: str = "trajectory", text: str | None = None,
           key: list[float] | None = None, episode: int | None = None, **kw: Any) -> StoredExperience:
    return StoredExperience(kind=kind, text=text if text is not None else f"trajectory {n}", instruction=instruction,
                            benchmark="eb_alfred", subset="base", episode=n if episode is None else episode,
                            task_id=f"task-{n if episode is None else episode}", success_signal="env",
                            key_embedding=key, run_id="run-1", **{"success": True, **kw})


def _add(store: ExperienceStore, entries: list[StoredExperience]) -> list[bool]:
    return asyncio.run(store.add(entries))


def test_store_satisfies_the_memory_protocol(embedder) -> None:
    assert isinstance(ExperienceStore(embedder), Memory)


def test_ids_are_deterministic_and_ignore_the_vector(unit) -> None:
    a, b = _entry(1), _entry(1, key=unit(1.0))
    assert a.id == b.id and len(a.id) == 20 and a.id != _entry(2).id


def test_embed_fills_the_key_from_the_key_text(embedder) -> None:
    store = ExperienceStore(embedder)
    plain, keyed = asyncio.run(store.embed([_entry(1), _entry(2, key=None).model_copy(update={"key": "spec"})]))
    assert np.allclose(plain.key_embedding, embedder.encode(["put apple in fridge"])[0])
    assert np.allclose(keyed.key_embedding, embedder.encode(["spec"])[0])


def test_retrieve_orders_by_cosine_then_insertion(embedder, unit, at_cosine) -> None:
    store = ExperienceStore(embedder)
    _add(store, [_entry(1, "a", key=at_cosine(0.5)), _entry(2, "b", key=at_cosine(0.9)),
                 _entry(3, "c", key=at_cosine(0.9)), _entry(4, "d", key=at_cosine(0.1), kind="workflow")])
    got = store.retrieve(unit(1.0), 3)
    assert [e.instruction for e in got] == ["b", "c", "a"]
    assert [e.instruction for e in store.retrieve(unit(1.0), 5, kind="workflow")] == ["d"]
    assert store.retrieve(unit(1.0), 0) == [] and all(e.key_embedding is None for e in got)


def test_exclude_instruction_is_normalised(embedder, unit, at_cosine) -> None:
    store = ExperienceStore(embedder)
    _add(store, [_entry(1, "Put the apple in the fridge.", key=at_cosine(0.99)), _entry(2, "other", key=at_cosine(0.2))])
    got = store.retrieve(unit(1.0), 2, exclude_instruction="put  the Apple in the fridge")
    assert [e.instruction for e in got] == ["other"]
    assert normalize_instruction(" A  b. ") == "a b"


def test_retrieve_groups_returns_whole_source_episodes(embedder, unit, at_cosine) -> None:
    store = ExperienceStore(embedder)
    _add(store, [_entry(1, "far", key=at_cosine(0.1), kind="memory_item", text="f1"),
                 _entry(2, "near", key=at_cosine(0.9), kind="memory_item", text="n1", episode=2),
                 _entry(3, "near", key=at_cosine(0.9), kind="memory_item", text="n2", episode=2),
                 _entry(4, "nearest", key=at_cosine(0.95), kind="trajectory", text="other kind")])
    groups = store.retrieve_groups(unit(1.0), 1, kind="memory_item")
    assert [[e.text for e in g] for g in groups] == [["n1", "n2"]]
    assert [[e.text for e in g] for g in store.retrieve_groups(unit(1.0), 5, kind="memory_item")] == [["n1", "n2"], ["f1"]]
    assert store.retrieve_groups(unit(1.0), 1, kind="memory_item", exclude_instruction="near")[0][0].text == "f1"


def test_latest_and_counts(embedder) -> None:
    store = ExperienceStore(embedder)
    _add(store, [_entry(1, kind="workflow", text="w1"), _entry(2), _entry(3, kind="workflow", text="w2")])
    assert store.latest("workflow").text == "w2" and store.latest("nothing") is None
    assert store.counts() == {"workflow": 2, "trajectory": 1} and len(store) == 3


def test_exact_text_dedup_only_when_asked(embedder) -> None:
    dedup, plain = ExperienceStore(embedder, dedup="text"), ExperienceStore(embedder)
    same = [_entry(1, text="same"), _entry(2, text="same")]
    assert _add(dedup, same) == [True, False] and dedup.rejected_duplicates == 1
    assert _add(plain, same) == [True, True]


def test_budget_in_episodes_and_entries(embedder) -> None:
    by_episode = ExperienceStore(embedder, budget=1, budget_unit="episodes")
    rows = [_entry(1, text="a", episode=1), _entry(2, text="b", episode=1), _entry(3, text="c", episode=2)]
    assert _add(by_episode, rows) == [True, True, False] and by_episode.rejected_budget == 1
    by_entry = ExperienceStore(embedder, budget=1, budget_unit="entries")
    assert _add(by_entry, rows) == [True, False, False]
    assert _add(ExperienceStore(embedder, budget=0), rows) == [False, False, False]
    with pytest.raises(ValueError):
        ExperienceStore(embedder, budget=-1)


def test_truncated_and_commits(embedder) -> None:
    store = ExperienceStore(embedder)
    _add(store, [_entry(1)])
    store.commit(0)
    _add(store, [_entry(2), _entry(3)])
    store.commit(1)
    cut = store.truncated(1)
    assert len(cut) == 1 and cut.commits == [[0, 1]] and cut.entries()[0].episode == 1
    assert len(store) == 3 and store.commits == [[0, 1], [1, 3]]


def test_copy_is_independent(embedder, unit) -> None:
    store = ExperienceStore(embedder)
    _add(store, [_entry(1)])
    store.commit(0)
    snap = store.copy()
    _add(snap, [_entry(2)])
    snap.commit(1)
    assert len(store) == 1 and store.commits == [[0, 1]]
    assert len(snap) == 2 and snap.commits == [[0, 1], [1, 2]]
    assert [e.episode for e in snap.retrieve(unit(1.0), 5)] != [] and len(store.retrieve(unit(1.0), 5)) == 1


def test_save_load_round_trip_with_load_from_disk(tmp_path, embedder) -> None:
    from datasets import load_from_disk

    store = ExperienceStore(embedder, budget=5, budget_unit="entries", dedup="text")
    _add(store, [_entry(1, kind="memory_item", title="T", description="D", text="item"),
                 _entry(2, success=False)])
    store.commit(4)
    path = tmp_path / "memory"
    store.save(path)
    data = load_from_disk(str(path))
    assert len(data) == 2 and data[0]["title"] == "T" and data[1]["success"] is False
    assert len(data[0]["key_embedding"]) == embedder.dim and "text_embedding" not in data.column_names
    back = ExperienceStore.load(str(path), embedder)
    assert [e.model_dump() for e in back.entries()] == [e.model_dump() for e in store.entries()]
    assert np.allclose([e.key_embedding for e in back.entries(with_embeddings=True)],
                       [e.key_embedding for e in store.entries(with_embeddings=True)])
    assert (back.budget, back.budget_unit, back.dedup, back.commits) == (5, "entries", "text", [[4, 2]])
    assert len(ExperienceStore.load(str(path), embedder, budget=1)) == 1
    store.save(path)   # saving again over an existing store is atomic and fine
    empty = ExperienceStore(embedder)
    empty.save(tmp_path / "empty")
    assert len(ExperienceStore.load(str(tmp_path / "empty"), embedder)) == 0


def test_entry_from_record_round_trips_the_runner_form(embedder) -> None:
    store = ExperienceStore(embedder)
    (embedded,) = asyncio.run(store.embed([_entry(1, title="t")]))
    record = embedded.model_dump(mode="json", exclude={"key_embedding", "text_embedding"})
    assert "key_embedding" not in record
    back = store.entry_from_record(record)
    assert back.id == embedded.id and back.key_embedding is None


def test_loading_refuses_another_embedder(tmp_path, embedder, embedder_cls) -> None:
    from worldmind_local.memory import MemoryDataError

    store = ExperienceStore(embedder)
    _add(store, [_entry(1)])
    store.save(tmp_path / "m")

    class Other(embedder_cls):
        model_id = "other/model"

    with pytest.raises(MemoryDataError, match="embedder"):
        ExperienceStore.load(str(tmp_path / "m"), Other())
