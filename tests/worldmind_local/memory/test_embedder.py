"""Embedder: cache, normalisation, and batching of concurrent aencode calls into one model call."""

from __future__ import annotations

import asyncio
import threading

import numpy as np
import pytest


def test_encode_shape_norm_and_cache(embedder) -> None:
    out = embedder.encode(["a", "b", "a"])
    assert out.dtype == np.float32 and out.shape == (3, 8)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-6)
    np.testing.assert_array_equal(out[0], out[2])
    assert embedder.calls == [["a", "b"]]            # duplicates within a call embedded once
    again = embedder.encode(["b", "c"])
    assert embedder.calls == [["a", "b"], ["c"]]     # "b" came from the cache
    np.testing.assert_array_equal(again[0], out[1])
    assert embedder.encode([]).shape == (0, 8)


def test_lru_cache_evicts_least_recently_used(embedder_cls) -> None:
    emb = embedder_cls(cache_size=2)
    emb.encode(["a", "b"])
    emb.encode(["a"])          # a is now most recent
    emb.encode(["c"])          # evicts b
    emb.encode(["a", "b"])
    assert emb.calls[-1] == ["b"]


def test_rejects_a_bare_string(embedder) -> None:
    with pytest.raises(TypeError):
        embedder.encode("a sentence")
    with pytest.raises(TypeError):
        embedder.encode(["ok", 3])


def test_concurrent_aencode_calls_share_one_model_call(embedder_cls) -> None:
    plain = embedder_cls()
    batched = embedder_cls()
    requests = [[f"text {i}", f"shared {i % 3}"] for i in range(10)]

    async def main() -> list[np.ndarray]:
        return list(await asyncio.gather(*(batched.aencode(r) for r in requests)))

    results = asyncio.run(main())
    assert len(batched.calls) == 1 and batched.model_calls == 1
    assert sorted(batched.calls[0]) == sorted({t for r in requests for t in r})
    for req, got in zip(requests, results, strict=True):
        np.testing.assert_array_equal(got, plain.encode(req))


def test_requests_during_an_encode_go_into_the_next_batch(embedder_cls) -> None:
    gate = threading.Event()

    class Slow(embedder_cls):  # type: ignore[misc, valid-type]
        def _embed_uncached(self, texts):  # noqa: ANN001, ANN202
            gate.wait(5)
            return super()._embed_uncached(texts)

    emb = Slow()

    async def main() -> None:
        first = asyncio.ensure_future(emb.aencode(["x"]))
        await asyncio.sleep(0.05)                      # the first batch is now encoding in the worker
        later = [asyncio.ensure_future(emb.aencode([f"y{i}", "x"])) for i in range(5)]
        await asyncio.sleep(0.05)
        gate.set()
        await asyncio.gather(first, *later)

    asyncio.run(main())
    assert emb.calls == [["x"], [f"y{i}" for i in range(5)]]   # "x" was in flight: shared, not re-sent


def test_cached_texts_do_not_reach_the_model(embedder) -> None:
    embedder.encode(["known"])
    out = asyncio.run(embedder.aencode(["known", "known"]))
    assert embedder.calls == [["known"]] and out.shape == (2, 8)


def test_encode_errors_reach_every_waiting_caller(embedder_cls) -> None:
    class Broken(embedder_cls):  # type: ignore[misc, valid-type]
        def _embed_uncached(self, texts):  # noqa: ANN001, ANN202
            raise RuntimeError("model exploded")

    emb = Broken()

    async def main() -> list[object]:
        return list(await asyncio.gather(emb.aencode(["a"]), emb.aencode(["b"]), return_exceptions=True))

    errors = asyncio.run(main())
    assert all(isinstance(e, RuntimeError) and "exploded" in str(e) for e in errors)


def test_usable_from_successive_event_loops(embedder) -> None:
    a = asyncio.run(embedder.aencode(["p"]))
    b = asyncio.run(embedder.aencode(["p", "q"]))
    np.testing.assert_array_equal(a[0], b[0])
    embedder.close()


def test_wrong_dimension_from_the_model_is_an_error(embedder_cls) -> None:
    class Wrong(embedder_cls):  # type: ignore[misc, valid-type]
        def _embed_uncached(self, texts):  # noqa: ANN001, ANN202
            return np.ones((len(texts), 3), dtype=np.float32)

    with pytest.raises(ValueError, match="expected shape"):
        Wrong().encode(["a"])


def test_a_cancelled_caller_does_not_cancel_the_others(embedder_cls) -> None:
    gate = threading.Event()

    class Slow(embedder_cls):  # type: ignore[misc, valid-type]
        def _embed_uncached(self, texts):  # noqa: ANN001, ANN202
            gate.wait(5)
            return super()._embed_uncached(texts)

    emb = Slow()

    async def main() -> np.ndarray:
        quitter = asyncio.ensure_future(emb.aencode(["same"]))
        stayer = asyncio.ensure_future(emb.aencode(["same"]))
        await asyncio.sleep(0.01)
        quitter.cancel()
        gate.set()
        return await stayer

    out = asyncio.run(main())
    np.testing.assert_array_equal(out[0], embedder_cls().encode(["same"])[0])
