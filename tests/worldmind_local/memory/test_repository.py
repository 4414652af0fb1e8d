"""WorldKnowledgeRepository mechanics with hand-chosen vectors: dedup, budget, top-k, exclusion, copy."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from worldmind_local.memory import WorldKnowledgeRepository


@pytest.fixture
def repo(embedder) -> WorldKnowledgeRepository:
    return WorldKnowledgeRepository(embedder)


def test_dedup_boundary_is_inclusive_at_095(repo, make_entry, unit, at_cosine) -> None:
    assert repo.add_embedded(make_entry(key=unit(1), vec=unit(1)))
    assert not repo.add_embedded(make_entry(key=unit(0, 1), vec=at_cosine(0.95)))      # == 0.95: duplicate
    assert repo.add_embedded(make_entry(key=unit(0, 1), vec=at_cosine(0.9499)))        # just below: kept
    assert not repo.add_embedded(make_entry(key=unit(0, 1), vec=unit(1)))              # identical text
    assert len(repo) == 2 and repo.rejected_duplicates == 2


def test_dedup_is_per_partition(repo, make_entry, unit) -> None:
    assert repo.add_embedded(make_entry("process", key=unit(1), vec=unit(1)))
    assert repo.add_embedded(make_entry("goal", key=unit(1), vec=unit(1)))     # same text, other partition
    assert not repo.add_embedded(make_entry("goal", key=unit(1), vec=unit(1)))
    assert repo.counts() == {"process": 1, "goal": 1}


def test_dedup_compares_texts_not_instructions(repo, make_entry, unit) -> None:
    assert repo.add_embedded(make_entry(key=unit(1), vec=unit(1)))
    assert repo.add_embedded(make_entry(key=unit(1), vec=unit(0, 1)))   # same task, different rule


def test_custom_threshold(embedder, make_entry, unit, at_cosine) -> None:
    repo = WorldKnowledgeRepository(embedder, dedup_threshold=0.8)
    assert repo.add_embedded(make_entry(key=unit(1), vec=unit(1)))
    assert not repo.add_embedded(make_entry(key=unit(1), vec=at_cosine(0.85)))
    with pytest.raises(ValueError):
        WorldKnowledgeRepository(embedder, dedup_threshold=0.0)


def test_budget_keeps_the_first_n_over_both_partitions(embedder, make_entry, unit) -> None:
    repo = WorldKnowledgeRepository(embedder, budget=3)
    offered = [make_entry("process" if i % 2 else "goal", key=unit(1), vec=unit(*([0] * i), 1)) for i in range(5)]
    assert [repo.add_embedded(e) for e in offered] == [True, True, True, False, False]
    assert len(repo) == 3 and repo.rejected_budget == 2
    assert [e.id for e in repo.entries()] == [e.id for e in offered[:3]]       # first come, first kept
    # a duplicate at full capacity counts as a duplicate, not as over budget
    assert not repo.add_embedded(make_entry("goal", key=unit(1), vec=unit(1)))
    assert repo.rejected_duplicates == 1 and repo.rejected_budget == 2


def test_budget_zero_is_mem0(embedder, make_entry, unit) -> None:
    repo = WorldKnowledgeRepository(embedder, budget=0)
    assert not repo.add_embedded(make_entry(key=unit(1), vec=unit(1)))
    assert len(repo) == 0
    with pytest.raises(ValueError):
        WorldKnowledgeRepository(embedder, budget=-1)


def test_top_k_order_and_ties_by_insertion(repo, make_entry, unit) -> None:
    keys = [unit(1, 0), unit(1, 1), unit(1, 0), unit(0, 1), unit(1, 0)]   # cos to e1: 1, .71, 1, 0, 1
    for i, key in enumerate(keys):
        repo.add_embedded(make_entry(text=f"r{i}", key=key, vec=unit(*([0] * i), 1)))
    top = lambda k: [e.text for e in repo.retrieve(np.array(unit(1)), "process", k)]  # noqa: E731
    assert top(1) == ["r0"]
    assert top(2) == ["r0", "r2"]
    assert top(3) == ["r0", "r2", "r4"]
    assert top(4) == ["r0", "r2", "r4", "r1"]
    assert top(10) == ["r0", "r2", "r4", "r1", "r3"]
    assert top(0) == [] and repo.retrieve(np.array(unit(1)), "goal", 2) == []


def test_query_is_normalised_and_checked(repo, make_entry, unit) -> None:
    repo.add_embedded(make_entry(text="a", key=unit(1, 0), vec=unit(1)))
    repo.add_embedded(make_entry(text="b", key=unit(0, 1), vec=unit(0, 1)))
    assert [e.text for e in repo.retrieve(np.array(unit(0, 1)) * 7, "process", 1)] == ["b"]
    assert [e.text for e in repo.retrieve(np.array([unit(0, 1)]), "process", 1)] == ["b"]   # (1, dim) ok
    with pytest.raises(ValueError, match="query"):
        repo.retrieve(np.ones(5), "process", 1)
    with pytest.raises(ValueError, match="partition"):
        repo.retrieve(np.array(unit(1)), "episodic", 1)


def test_self_exclusion_skips_the_identical_instruction(repo, make_entry, unit) -> None:
    repo.add_embedded(make_entry("goal", text="own", instruction="task A", key=unit(1), vec=unit(1)))
    repo.add_embedded(make_entry("goal", text="other", instruction="task B", key=unit(1, 1), vec=unit(0, 1)))
    repo.add_embedded(make_entry("goal", text="own2", instruction="task A", key=unit(1), vec=unit(0, 0, 1)))
    q = np.array(unit(1))
    assert [e.text for e in repo.retrieve(q, "goal", 2)] == ["own", "own2"]
    assert [e.text for e in repo.retrieve(q, "goal", 2, exclude_instruction="task A")] == ["other"]
    assert repo.retrieve(q, "goal", 1, exclude_instruction="task B")[0].text == "own"


def test_copy_is_independent(embedder, make_entry, unit) -> None:
    repo = WorldKnowledgeRepository(embedder, dedup_threshold=1.0)   # only identical texts are duplicates
    repo.add_embedded(make_entry(text="base", key=unit(1), vec=unit(1)))
    snap = repo.copy()
    assert snap.add_embedded(make_entry(text="snap", key=unit(0, 1), vec=unit(0, 1)))
    assert repo.add_embedded(make_entry(text="orig", key=unit(0, 0, 1), vec=unit(0, 0, 1)))
    assert [e.text for e in repo.entries()] == ["base", "orig"]
    assert [e.text for e in snap.entries()] == ["base", "snap"]
    assert repo.retrieve(np.array(unit(0, 1)), "process", 1)[0].text != "snap"
    # growing past the initial capacity in one copy leaves the other untouched
    for i in range(100):
        angle = (i + 1) * np.pi / 300
        assert snap.add_embedded(make_entry(text=f"s{i}", key=unit(1), vec=unit(0, 0, 0, np.cos(angle), np.sin(angle))))
    assert len(repo) == 2 and len(snap) == 102


def test_add_embeds_missing_vectors_in_one_call(repo, embedder, make_entry) -> None:
    entries = [make_entry(text="rule one", instruction="task"), make_entry("goal", text="flow", instruction="task")]
    assert asyncio.run(repo.add(entries)) == [True, True]
    assert len(embedder.calls) == 1 and sorted(embedder.calls[0]) == ["flow", "rule one", "task"]
    got = repo.entries(with_embeddings=True)
    np.testing.assert_array_equal(np.array(got[0].key_embedding, np.float32), embedder.encode(["task"])[0])
    np.testing.assert_array_equal(np.array(got[1].text_embedding, np.float32), embedder.encode(["flow"])[0])
    assert all(e.key_embedding is None for e in repo.entries())    # plain listing: no vectors
    assert asyncio.run(repo.add([make_entry(text="rule one", instruction="other")])) == [False]


def test_embed_returns_entries_ready_for_the_record(repo, make_entry) -> None:
    [e] = asyncio.run(repo.embed([make_entry(text="r")]))
    assert e.embedded and len(e.key_embedding) == 8
    assert repo.add_embedded(e) and len(repo) == 1


def test_add_embedded_checks_vectors(repo, make_entry, unit) -> None:
    with pytest.raises(ValueError, match="missing"):
        repo.add_embedded(make_entry(key=unit(1)))
    with pytest.raises(ValueError, match="shape"):
        repo.add_embedded(make_entry(key=[1.0, 0.0], vec=unit(1)))
    with pytest.raises(ValueError, match="zero"):
        repo.add_embedded(make_entry(key=unit(1), vec=[0.0] * 8))


def test_unnormalised_vectors_are_normalised(repo, make_entry, unit) -> None:
    repo.add_embedded(make_entry(key=[3.0] + [0.0] * 7, vec=[0.0, 2.0] + [0.0] * 6))
    e = repo.entries(with_embeddings=True)[0]
    assert e.key_embedding == unit(1) and e.text_embedding == unit(0, 1)
    assert not repo.add_embedded(make_entry(key=unit(1), vec=[0.0, 5.0] + [0.0] * 6))
