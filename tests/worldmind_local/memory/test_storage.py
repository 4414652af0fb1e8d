"""Saving and loading the repository as a Hugging Face dataset: round trip, empty, atomicity, metadata."""

from __future__ import annotations

import json

import datasets
import numpy as np
import pytest

from worldmind_local.memory import MemoryDataError, WorldKnowledgeRepository


@pytest.fixture
def filled(embedder, make_entry, unit) -> WorldKnowledgeRepository:
    repo = WorldKnowledgeRepository(embedder, budget=10)
    repo.add_embedded(make_entry("process", text="p0", instruction="A", key=unit(1), vec=unit(1), step=3,
                                 action="open the Fridge", predicted_state="fridge open",
                                 actual_state="fridge closed", judge_reason="contradiction",
                                 planner_model="hf:smollm2", judge_model="hf:smollm2", run_id="r1"))
    repo.add_embedded(make_entry("goal", text="g0", instruction="B", key=unit(0, 1), vec=unit(1)))
    repo.add_embedded(make_entry("process", text="p1", instruction="B", key=unit(1, 1), vec=unit(0, 1)))
    return repo


def _same(a: WorldKnowledgeRepository, b: WorldKnowledgeRepository) -> None:
    assert [e.model_dump() for e in a.entries(with_embeddings=True)] == \
        [e.model_dump() for e in b.entries(with_embeddings=True)]


def test_round_trip_keeps_order_provenance_and_vectors(filled, embedder, tmp_path) -> None:
    filled.save(tmp_path / "memory")
    back = WorldKnowledgeRepository.load(tmp_path / "memory", embedder)
    _same(filled, back)
    assert back.budget == 10 and back.dedup_threshold == 0.95
    q = np.array(filled.entries(with_embeddings=True)[2].key_embedding)
    assert [e.id for e in back.retrieve(q, "process", 2)] == [e.id for e in filled.retrieve(q, "process", 2)]


def test_plain_load_from_disk_shows_provenance_and_fixed_length_vectors(filled, tmp_path) -> None:
    filled.save(tmp_path / "memory")
    ds = datasets.load_from_disk(str(tmp_path / "memory"))
    assert len(ds) == 3 and ds["text"] == ["p0", "g0", "p1"] and ds["partition"] == ["process", "goal", "process"]
    for col in ("benchmark", "subset", "episode", "step", "action", "predicted_state", "actual_state",
                "judge_reason", "planner_model", "judge_model", "run_id", "task_id", "instruction"):
        assert col in ds.column_names
    assert ds[0]["judge_reason"] == "contradiction" and ds[1]["step"] is None
    feature = ds.features["key_embedding"]
    assert feature.length == 8 and feature.feature.dtype == "float32"
    assert ds.data.schema.field("text_embedding").type.list_size == 8
    meta = json.loads(ds.info.description)
    assert meta["embedder_model_id"] == "test/hash-embedder" and meta["dim"] == 8
    assert meta["dedup_threshold"] == 0.95 and meta["budget"] == 10
    assert meta["counts"] == {"process": 2, "goal": 1}


def test_empty_repository_saves_and_loads(embedder, tmp_path) -> None:
    WorldKnowledgeRepository(embedder).save(tmp_path / "empty")
    ds = datasets.load_from_disk(str(tmp_path / "empty"))
    assert len(ds) == 0 and ds.features["key_embedding"].length == 8
    back = WorldKnowledgeRepository.load(tmp_path / "empty", embedder)
    assert len(back) == 0 and back.retrieve(np.ones(8), "goal", 2) == []


def test_resave_replaces_and_leaves_no_temporaries(filled, embedder, make_entry, unit, tmp_path) -> None:
    path = tmp_path / "memory"
    filled.save(path)
    filled.add_embedded(make_entry("goal", text="g1", key=unit(1), vec=unit(0, 0, 1)))
    filled.save(path)
    assert len(datasets.load_from_disk(str(path))) == 4
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory"]


def test_failed_save_leaves_the_old_folder_intact(filled, embedder, make_entry, unit, tmp_path,
                                                  monkeypatch) -> None:
    path = tmp_path / "memory"
    filled.save(path)
    before = sorted((p.name, p.read_bytes()) for p in path.iterdir())
    filled.add_embedded(make_entry("goal", text="g1", key=unit(1), vec=unit(0, 0, 1)))

    def half_write(self, dataset_path, **kw):  # noqa: ANN001, ANN003, ANN202
        from pathlib import Path
        (Path(dataset_path) / "data-00000-of-00001.arrow").write_bytes(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(datasets.Dataset, "save_to_disk", half_write)
    with pytest.raises(OSError, match="disk full"):
        filled.save(path)
    monkeypatch.undo()
    assert sorted((p.name, p.read_bytes()) for p in path.iterdir()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory"]
    assert len(WorldKnowledgeRepository.load(path, embedder)) == 3


def test_stale_temporaries_from_a_killed_save_are_removed(filled, tmp_path) -> None:
    (tmp_path / ".memory.tmp-abc").mkdir()
    (tmp_path / ".memory.tmp-abc" / "junk").write_text("x")
    filled.save(tmp_path / "memory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory"]


def test_refuses_to_overwrite_something_that_is_not_a_dataset(filled, tmp_path) -> None:
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "thesis.tex").write_text("precious")
    with pytest.raises(FileExistsError):
        filled.save(tmp_path / "notes")
    assert (tmp_path / "notes" / "thesis.tex").read_text() == "precious"


def test_load_accepts_dataset_and_datasetdict(filled, embedder) -> None:
    ds = filled.to_dataset()
    _same(filled, WorldKnowledgeRepository.load(ds, embedder))
    by_split = datasets.DatasetDict({
        "process": ds.filter(lambda r: r["partition"] == "process").remove_columns("partition"),
        "goal": ds.filter(lambda r: r["partition"] == "goal").remove_columns("partition"),
    })
    back = WorldKnowledgeRepository.load(by_split, embedder)
    assert back.counts() == {"process": 2, "goal": 1} and back.embedder_model_id == "test/hash-embedder"


def test_explicit_settings_override_stored_ones_and_budget_truncates(filled, embedder) -> None:
    ds = filled.to_dataset()
    unbounded = WorldKnowledgeRepository.from_dataset(ds, embedder, budget=None, dedup_threshold=0.9)
    assert unbounded.budget is None and unbounded.dedup_threshold == 0.9
    small = WorldKnowledgeRepository.from_dataset(ds, embedder, budget=2)
    assert [e.text for e in small.entries()] == ["p0", "g0"]


def test_load_without_embedder_uses_stored_settings(filled) -> None:
    back = WorldKnowledgeRepository.from_dataset(filled.to_dataset())
    assert back.dim == 8 and back.embedder_model_id == "test/hash-embedder" and len(back) == 3


def test_mismatched_embedder_is_refused(filled, embedder_cls) -> None:
    class Other(embedder_cls):  # type: ignore[misc, valid-type]
        model_id = "test/other"

    class Wider(embedder_cls):  # type: ignore[misc, valid-type]
        dim = 16

    with pytest.raises(MemoryDataError, match="embedder_model_id"):
        WorldKnowledgeRepository.from_dataset(filled.to_dataset(), Other())
    with pytest.raises(MemoryDataError, match="key_embedding"):
        WorldKnowledgeRepository.from_dataset(filled.to_dataset(), Wider())


def test_null_embeddings_are_computed_on_load(embedder) -> None:
    rows = {"partition": ["process", "goal"], "text": ["rule", "flow"], "instruction": ["t1", "t2"],
            "benchmark": ["eb_alfred"] * 2, "subset": ["base"] * 2, "episode": [0, 1], "task_id": ["a", "b"]}
    repo = WorldKnowledgeRepository.load(datasets.Dataset.from_dict(rows), embedder)
    got = repo.entries(with_embeddings=True)
    np.testing.assert_array_equal(np.array(got[0].key_embedding, np.float32), embedder.encode(["t1"])[0])
    np.testing.assert_array_equal(np.array(got[1].text_embedding, np.float32), embedder.encode(["flow"])[0])


def test_malformed_rows_name_row_and_field(embedder) -> None:
    rows = {"partition": ["process", "episodic"], "text": ["r", "s"], "instruction": ["t", "t"],
            "benchmark": ["b"] * 2, "subset": ["s"] * 2, "episode": [0, 1], "task_id": ["a", "b"]}
    with pytest.raises(MemoryDataError, match=r"row 1: field 'partition'"):
        WorldKnowledgeRepository.load(datasets.Dataset.from_dict(rows), embedder)
    with pytest.raises(MemoryDataError, match="'instruction'"):
        WorldKnowledgeRepository.load(datasets.Dataset.from_dict({k: v for k, v in rows.items()
                                                                  if k != "instruction"}), embedder)
    bad_dim = {**rows, "partition": ["process"] * 2, "key_embedding": [[1.0, 0.0]] * 2}
    with pytest.raises(MemoryDataError, match=r"row 0: field 'key_embedding'"):
        WorldKnowledgeRepository.load(datasets.Dataset.from_dict(bad_dim), embedder)


def test_missing_folder_is_a_clear_error(tmp_path) -> None:
    with pytest.raises(FileNotFoundError, match="no World Knowledge Repository"):
        WorldKnowledgeRepository.load(tmp_path / "nope")


def test_save_without_atomic_exchange_support(filled, embedder, tmp_path, monkeypatch) -> None:
    from worldmind_local.memory import storage

    monkeypatch.setattr(storage, "_exchange", lambda a, b: False)
    filled.save(tmp_path / "memory")
    filled.save(tmp_path / "memory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["memory"]
    _same(filled, WorldKnowledgeRepository.load(tmp_path / "memory", embedder))


def test_load_respects_a_selected_view(filled, embedder) -> None:
    view = filled.to_dataset().select([2, 0])
    assert [e.text for e in WorldKnowledgeRepository.load(view, embedder).entries()] == ["p1", "p0"]
