"""`--perturb poison:RATE`: exactly that share of a seeded repository, reproducible per seed, recorded."""

from __future__ import annotations

import asyncio
import json

import pytest

from worldmind_local.perturb.poison import parse_perturb, poison_indices, poison_memory, with_poison
from worldmind_local.runner.config import StreamSpec


@pytest.fixture(scope="module")
def embedder():
    from worldmind_local.memory import Embedder

    return Embedder()


def _repository(embedder, n: int = 20):
    from worldmind_local.memory import WorldKnowledgeRepository
    from worldmind_local.memory.entries import ExperienceEntry

    repo = WorldKnowledgeRepository(embedder)
    objects = ["Apple", "Mug", "Knife", "Bread", "Egg", "Plate", "Pan", "Cup", "Bowl", "Potato"]
    entries = [ExperienceEntry(
        partition="process" if i % 2 else "goal",
        text=(f"Rule {i}: open the Fridge before picking up the {objects[i % 10]} number {i}" if i % 2 else
              f"Workflow {i}: 1. find a {objects[i % 10]}. 2. pick it up. 3. put it in bin {i}."),
        instruction=f"task {i}: move the {objects[i % 10]}", benchmark="eb_alfred", subset="base",
        episode=i, task_id=f"t{i}") for i in range(n)]
    kept = asyncio.run(repo.add(entries))
    assert all(kept)
    return repo


def test_parse_perturb() -> None:
    assert parse_perturb("poison:0.20") == "poison:0.2" == parse_perturb("poison:20%")
    assert parse_perturb("rename") == "rename" and parse_perturb(None) is None
    for bad in ("poison:0", "poison:1.5", "poison:x", "shuffle"):
        with pytest.raises(ValueError):
            parse_perturb(bad)
    with pytest.raises(ValueError, match="RATE"):
        StreamSpec(benchmark="eb_alfred", subset="base", planner="random:seeded-random", perturb="poison:2")


def test_indices_exact_share_and_seeded() -> None:
    assert len(poison_indices(20, 0.2, 0)) == 4
    assert len(poison_indices(7, 0.2, 0)) == 1 and len(poison_indices(5, 1.0, 0)) == 5
    assert poison_indices(50, 0.2, 3) == poison_indices(50, 0.2, 3)
    assert poison_indices(50, 0.2, 3) != poison_indices(50, 0.2, 4)


def test_poisoning_20_percent_changes_exactly_that_share(embedder) -> None:
    repo = _repository(embedder, 20)
    before = repo.entries()
    poisoned, report = poison_memory(repo, rate=0.2, seed=5, benchmark="eb_alfred", embedder=embedder)
    after = poisoned.entries()
    assert len(after) == len(before) == 20
    changed = [i for i, (a, b) in enumerate(zip(before, after, strict=True)) if a.text != b.text]
    assert len(changed) == 4 == report["poisoned"]
    assert changed == [r["position"] for r in report["replaced"]] == poison_indices(20, 0.2, 5)
    for item in report["replaced"]:
        old, new = before[item["position"]], after[item["position"]]
        assert item["original"]["text"] == old.text and item["original"]["id"] == old.id
        assert item["poisoned_id"] == new.id != old.id and new.text == item["poisoned_text"]
        assert (new.instruction, new.partition, new.task_id) == (old.instruction, old.partition, old.task_id)
    # the untouched entries are the same records; the repository's original is not modified
    assert all(before[i] == after[i] for i in range(20) if i not in changed)
    assert [e.text for e in repo.entries()] == [e.text for e in before]
    # a poisoned rule is retrieved where the original was (its instruction embedding is unchanged)
    query = embedder.encode([before[changed[0]].instruction])[0]
    top = poisoned.retrieve(query, before[changed[0]].partition, 1)
    assert top[0].id == report["replaced"][0]["poisoned_id"]


def test_poisoning_is_reproducible_per_seed(embedder) -> None:
    repo = _repository(embedder, 20)
    a, ra = poison_memory(repo, rate=0.2, seed=1, benchmark="eb_alfred", embedder=embedder)
    b, rb = poison_memory(repo, rate=0.2, seed=1, benchmark="eb_alfred", embedder=embedder)
    c, rc = poison_memory(repo, rate=0.2, seed=2, benchmark="eb_alfred", embedder=embedder)
    assert [e.text for e in a.entries()] == [e.text for e in b.entries()] and ra == rb
    assert [e.text for e in a.entries()] != [e.text for e in c.entries()]


def test_with_poison_writes_the_record_and_skips_empty_memories(embedder, tmp_path, capsys) -> None:
    repo = _repository(embedder, 10)
    make = with_poison(lambda: repo, "poison:0.3", seed=0, benchmark="eb_alfred", stream_root=tmp_path / "s",
                       embedder=embedder, stream_id="s")
    memory = make()
    record = json.loads((tmp_path / "s" / "poison.json").read_text())
    assert record["poisoned"] == 3 and len(memory) == 10
    assert with_poison(lambda: repo, None, seed=0, benchmark="eb_alfred", stream_root=tmp_path)() is repo
    from worldmind_local.memory import WorldKnowledgeRepository

    empty = WorldKnowledgeRepository(embedder)
    assert len(with_poison(lambda: empty, "poison:0.5", seed=0, benchmark="eb_alfred",
                           stream_root=tmp_path / "e")()) == 0
    assert "nothing to poison" in capsys.readouterr().err
