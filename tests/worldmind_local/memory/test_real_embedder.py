"""End to end with the real all-MiniLM-L6-v2 (offline package): paraphrases dedup, distinct rules stay."""

from __future__ import annotations

import asyncio

import datasets
import numpy as np
import pytest

from worldmind_local.memory import Embedder, ExperienceEntry, WorldKnowledgeRepository

pytestmark = pytest.mark.slow

RULE = "You must navigate to the countertop before putting an object on it."
PARAPHRASES = [
    "You must navigate to the countertop before you put an object on it.",
    "Before putting an object on the countertop, you must navigate to it.",
    "you must navigate to the countertop before putting an object on it",
]
DISTINCT = [
    "Open the fridge before trying to take an object out of it.",
    "Open the drawer before trying to take an object out of it.",
    "A knife must be held before slicing a tomato or a potato.",
]


@pytest.fixture(scope="module")
def real() -> Embedder:
    return Embedder()


def _entry(text: str, i: int, partition: str = "process") -> ExperienceEntry:
    return ExperienceEntry(partition=partition, text=text, instruction=f"Put a mug on the counter ({i}).",
                           benchmark="eb_alfred", subset="base", episode=i, task_id=f"base-{i}", step=1,
                           action="put down the object in hand", run_id="test")


def test_real_embeddings_are_384_dim_unit_vectors(real) -> None:
    out = real.encode([RULE, *DISTINCT])
    assert out.shape == (4, 384) and out.dtype == np.float32 and real.dim == 384
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-5)
    fresh = Embedder()
    fresh._model = real._model             # share the loaded weights; fresh cache and counters

    async def both() -> list[np.ndarray]:
        return list(await asyncio.gather(fresh.aencode([RULE]), fresh.aencode(DISTINCT)))

    got = asyncio.run(both())
    assert fresh.model_calls == 1
    np.testing.assert_array_equal(np.concatenate(got), out)


def test_a_vector_does_not_depend_on_its_batch(real) -> None:
    real.encode(["load the model"])
    uncached = Embedder(cache_size=0)
    uncached._model = real._model          # same weights, no cache: every call reaches the model
    words = "put the apple in fridge open drawer navigate to countertop before slicing knife tomato".split()
    rng = np.random.default_rng(0)
    texts = [" ".join(rng.choice(words, size=n)) for n in (1, 3, 9, 14, 20, 27, 33, 45, 60)]
    together = uncached.encode(texts)
    alone = np.stack([uncached.encode([t])[0] for t in texts])
    partial = uncached.encode(texts[3:6])
    np.testing.assert_array_equal(together, alone)
    np.testing.assert_array_equal(together[3:6], partial)
    from sentence_transformers import SentenceTransformer

    assert isinstance(real._model, SentenceTransformer)
    reference = real._model.encode(texts, normalize_embeddings=True, convert_to_numpy=True)
    np.testing.assert_allclose(together, reference, atol=1e-5)


def test_paraphrases_are_deduplicated_distinct_rules_kept_and_reload(real, tmp_path) -> None:
    repo = WorldKnowledgeRepository(real)
    texts = [RULE, *PARAPHRASES, *DISTINCT]
    kept = asyncio.run(repo.add([_entry(t, i) for i, t in enumerate(texts)]))
    assert kept == [True, False, False, False, True, True, True]
    assert asyncio.run(repo.add([_entry(PARAPHRASES[0], 99, "goal")])) == [True]   # other partition
    query = real.encode(["Put a mug on the counter (4)."])[0]
    assert repo.retrieve(query, "process", 1)[0].text == DISTINCT[0]

    repo.save(tmp_path / "memory")
    ds = datasets.load_from_disk(str(tmp_path / "memory"))
    assert len(ds) == 5 and ds.features["key_embedding"].length == 384
    assert ds.features["text_embedding"].feature.dtype == "float32"
    assert ds[0]["action"] == "put down the object in hand" and ds[0]["run_id"] == "test"
    back = WorldKnowledgeRepository.load(tmp_path / "memory", real)
    assert [e.text for e in back.entries()] == [e.text for e in repo.entries()]
    assert [e.text for e in back.retrieve(query, "process", 2)] == [e.text for e in repo.retrieve(query, "process", 2)]
