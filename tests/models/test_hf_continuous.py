"""Continuous batching on the hf backend (`models.hf_continuous`), with SmolLM2 in float32 so token
sequences can be compared exactly: joining a running batch must not change what a row decodes."""

from __future__ import annotations

import asyncio
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from models.base import ChatRequest, Sampling
from models.specs import load_spec, make_backend

sys.path.insert(0, str(Path(__file__).parent))
from test_hf_backend import _mixed_system_requests  # noqa: E402

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def smollm2_f32() -> Iterator[Any]:
    backend = make_backend(load_spec("hf:smollm2-135m-instruct"), dtype="float32")
    yield backend
    asyncio.run(backend.aclose())


async def _staggered(backend: Any, requests: list[ChatRequest], gap_s: float) -> list[str]:
    """Each request from its own caller, `gap_s` after the previous one: later ones join a running batch."""
    async def one(i: int, request: ChatRequest) -> str:
        await asyncio.sleep(gap_s * i)
        return (await backend.complete([request]))[0].texts[0]

    return list(await asyncio.gather(*(one(i, r) for i, r in enumerate(requests))))


def test_rows_joining_a_running_batch_decode_what_they_decode_alone(smollm2_f32: Any) -> None:
    requests = _mixed_system_requests()
    assert smollm2_f32.continuous

    async def run() -> tuple[list[str], list[str], list[str], int, int]:
        alone = [(await smollm2_f32.complete([r]))[0].texts[0] for r in requests]
        batched = [r.texts[0] for r in await smollm2_f32.complete(requests)]
        admissions = smollm2_f32.generate_calls
        steps = smollm2_f32.decode_steps
        joined = await _staggered(smollm2_f32, requests, 0.25)
        return alone, batched, joined, smollm2_f32.generate_calls - admissions, smollm2_f32.decode_steps - steps

    alone, batched, joined, admissions, steps = asyncio.run(run())
    assert batched == alone
    assert joined == alone
    assert admissions > 1  # the staggered callers were admitted one by one ...
    total = sum(len(smollm2_f32.tokenizer(t)["input_ids"]) for t in joined)
    assert steps < total  # ... into one running batch: fewer decode steps than tokens decoded


def test_continuous_and_static_batches_agree() -> None:
    requests = _mixed_system_requests()

    async def outputs(continuous: bool) -> list[str]:
        backend = make_backend(load_spec("hf:smollm2-135m-instruct"), dtype="float32", continuous=continuous)
        try:
            assert backend.continuous is continuous
            batched = [r.texts[0] for r in await backend.complete(requests)]
            return batched + await _staggered(backend, requests[:3], 0.25)
        finally:
            await backend.aclose()

    assert asyncio.run(outputs(True)) == asyncio.run(outputs(False))


def test_finished_rows_leave_and_their_columns_are_trimmed(smollm2_f32: Any) -> None:
    """A long-prompt row that finishes first is cut out of the cache; the batch shrinks to the rest."""
    import torch

    from models.constrained import RowControl
    from models.hf_continuous import RunningBatch, Slot

    backend = smollm2_f32
    long_row = backend._prepare(0, ChatRequest(messages=[{"role": "user", "content": "kitchen " * 200}]))
    short_row = backend._prepare(1, ChatRequest(messages=[{"role": "user", "content": "Say hi."}]))
    running = RunningBatch(backend.model, backend.eos_ids, backend.grammars.vocab_size)

    def admit(ids: list[int], max_tokens: int) -> Slot:
        slot = Slot(owner=None, index=0, control=RowControl(max_tokens))
        with torch.inference_mode():
            input_ids = torch.tensor([ids])
            running.admit([slot], input_ids, torch.ones_like(input_ids), _empty_cache(backend))
        return slot

    short = admit(short_row[3], 6)
    with torch.inference_mode():
        running.step()
    long = admit(long_row[3], 2)  # joins the running batch: the short row is left-padded to its length
    assert len(running) == 2 and running.length == len(long_row[3])
    finished: list[Slot] = []
    with torch.inference_mode():
        while running.slots:
            now = running.step()
            finished += now
            if long in now:
                assert running.slots == [short]
                assert running.length == len(short_row[3]) + len(short.tokens) - 1  # prompt + fed tokens
    assert finished[0] is long and len(long.tokens) == 2 and len(short.tokens) == 6
    assert running.cache is None and running.mask is None


def test_decode_steps_write_the_cache_in_place_and_decode_as_a_growing_cache(smollm2_f32: Any) -> None:
    """`BufferLayer`: a step writes its column into the preallocated buffer (no copy of the cache), and
    the masked unwritten columns change nothing: the same tokens as transformers' own growing cache."""
    import torch

    from models.constrained import RowControl
    from models.hf_continuous import BufferLayer, RunningBatch, Slot

    backend = smollm2_f32
    prompts = [backend._prepare(i, ChatRequest(messages=[{"role": "user", "content": text}]))[3]
               for i, text in enumerate(["Name three kitchen objects.", "Count from one to ten, in words, slowly."])]

    def decode(buffered: bool) -> tuple[list[list[int]], list[tuple[int, int]]]:
        running = RunningBatch(backend.model, backend.eos_ids, backend.grammars.vocab_size)
        if not buffered:
            running._own_cache = lambda: None  # leave transformers' DynamicLayers in place
        slots = [Slot(owner=None, index=0, control=RowControl(24)) for _ in prompts]
        width = max(len(ids) for ids in prompts)
        input_ids = torch.tensor([[0] * (width - len(ids)) + ids for ids in prompts])
        mask = torch.tensor([[0] * (width - len(ids)) + [1] * len(ids) for ids in prompts])
        storage: list[tuple[int, int]] = []  # (rows, address of layer 0's keys) before each step
        with torch.inference_mode():
            running.admit(slots, input_ids, mask, _empty_cache(backend))
            while running.slots:
                layer = running.cache.layers[0]
                assert isinstance(layer, BufferLayer) is buffered
                storage.append((len(running), layer.keys.data_ptr()))
                running.step()
        return [s.tokens for s in slots], storage

    (buffered, storage), (grown, grown_storage) = decode(True), decode(False)
    assert buffered == grown and min(len(t) for t in buffered) > 10
    # one buffer while the same rows run (a new one only when a row leaves) ...
    assert len(set(storage)) == len({rows for rows, _ in storage}) < len(storage) / 5
    # ... where torch.cat made a new tensor every step (while the old one was alive: a new address)
    assert all(a != b for a, b in zip(grown_storage, grown_storage[1:], strict=False))


def _empty_cache(backend: Any) -> Any:
    from transformers import DynamicCache

    return DynamicCache(config=backend.model.config)


def test_a_cancelled_caller_leaves_the_batch(smollm2_f32: Any) -> None:
    long = ChatRequest(messages=[{"role": "user", "content": "Write a long story about a robot."}],
                       sampling=Sampling(max_tokens=400))
    short = ChatRequest(messages=[{"role": "user", "content": "Say hi."}], sampling=Sampling(max_tokens=8))

    async def run() -> Any:
        uncut = (await smollm2_f32.complete([replace(long, sampling=Sampling(max_tokens=120))]))[0]
        assert uncut.completion_tokens == 120  # left alone, this request runs past 100 steps
        task = asyncio.ensure_future(smollm2_f32.complete([long]))
        await asyncio.sleep(0.5)
        task.cancel()
        steps = smollm2_f32.decode_steps
        result = (await smollm2_f32.complete([short]))[0]
        return result, smollm2_f32.decode_steps - steps

    result, steps = asyncio.run(run())
    assert result.completion_tokens <= 8
    assert steps < 100  # the story row was dropped, not decoded to 400 tokens


def test_a_model_error_fails_the_running_rows_and_the_next_request_is_served(smollm2_f32: Any) -> None:
    from models.base import BackendError

    model = smollm2_f32.model
    original = model.forward
    calls = {"decode": 0}

    def failing_once(*args: Any, **kwargs: Any) -> Any:
        if kwargs["input_ids"].shape[1] == 1 and calls["decode"] == 0:  # the first decode step
            calls["decode"] += 1
            raise RuntimeError("simulated kernel failure")
        return original(*args, **kwargs)

    ask = ChatRequest(messages=[{"role": "user", "content": "Say hi."}], sampling=Sampling(max_tokens=8))
    model.forward = failing_once
    try:
        async def run() -> Any:
            results = await asyncio.gather(smollm2_f32.complete([ask]), smollm2_f32.complete([ask]),
                                           return_exceptions=True)
            return results, await smollm2_f32.complete([ask])

        (first, second), after = asyncio.run(run())
    finally:
        del model.forward  # back to the class method
    for failed in (first, second):
        assert isinstance(failed, BackendError) and "simulated kernel failure" in str(failed)
    assert after[0].completion_tokens > 0


def test_n_rows_of_one_request_share_one_prefill(smollm2_f32: Any) -> None:
    """A request with n=3 is prefilled once (its prompt's tokens, not 3x), and its row k decodes what a
    separate n=1 request seeded seed+k decodes: the rows only share the prompt's key/value prefix."""
    system = {"role": "system", "content": "You answer in one short sentence about fruit and kitchens."}
    messages = [system, {"role": "user", "content": "Name a fruit that is good in a salad, and say why."}]
    many = ChatRequest(messages=messages, sampling=Sampling(temperature=0.7, max_tokens=10, seed=11, n=3))
    singles = [replace(many, sampling=replace(many.sampling, n=1, seed=11 + k)) for k in range(3)]

    async def run() -> tuple[list[str], int, list[str], int]:
        await smollm2_f32.complete([singles[0]])  # the system prefix is now cached for both runs
        before = smollm2_f32.prefilled_tokens
        result = (await smollm2_f32.complete([many]))[0]
        n_prefilled = smollm2_f32.prefilled_tokens - before
        before = smollm2_f32.prefilled_tokens
        alone = [(await smollm2_f32.complete([r]))[0] for r in singles]
        return result.texts, n_prefilled, [a.text for a in alone], (smollm2_f32.prefilled_tokens - before) // 3

    texts, n_prefilled, alone, per_single = asyncio.run(run())
    assert len(texts) == 3 and texts == alone
    assert n_prefilled == per_single > 0  # one prompt's worth of prefill for the three rows
