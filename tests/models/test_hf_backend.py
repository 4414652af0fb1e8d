"""The hf backend with real models: SmolLM2 (structured plans, batching, limits, seeds), tiny Qwen3 and
tiny Qwen3-VL (an image goes in). One model load per model for the whole file."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Iterator
from typing import Any

import pytest

from models.base import BackendError, ChatRequest, ContextLengthError, Sampling
from models.check import PLAN_SCHEMA, plan_is_valid, planner_requests
from models.specs import load_spec, make_backend

pytestmark = pytest.mark.slow


def _run(coro: Any) -> Any:
    return asyncio.run(coro)


@pytest.fixture(scope="module")
def smollm2() -> Iterator[Any]:
    backend = make_backend("hf:smollm2-135m-instruct")
    yield backend
    _run(backend.aclose())


@pytest.fixture(scope="module")
def tiny_qwen3() -> Iterator[Any]:
    backend = make_backend("hf:tiny-qwen3")
    yield backend
    _run(backend.aclose())


def _ask(text: str, **sampling: Any) -> ChatRequest:
    return ChatRequest(messages=[{"role": "user", "content": text}], sampling=Sampling(**sampling))


def test_eight_concurrent_plans_parse_and_share_one_generate(smollm2: Any) -> None:
    requests = planner_requests(8, max_tokens=128)
    calls_before = smollm2.generate_calls

    async def concurrently() -> list[Any]:  # eight callers, as eight streams of a run would be
        return await asyncio.gather(*(smollm2.complete([r]) for r in requests))

    results = [batch[0] for batch in _run(concurrently())]
    assert smollm2.generate_calls == calls_before + 1
    assert smollm2.batch_sizes[-1] == 8
    for result in results:
        assert plan_is_valid(result.text), result.text
        plan = json.loads(result.text)
        assert all(0 <= step["action_id"] <= 11 for step in plan["executable_plan"])
        assert result.model == "HuggingFaceTB/SmolLM2-135M-Instruct"
        assert 0 < result.completion_tokens <= 128 and result.latency_s > 0


def test_token_counts_are_per_request(smollm2: Any) -> None:
    short, long = _ask("Hi.", max_tokens=6), _ask("Describe a kitchen with a fridge and a sink. " * 5, max_tokens=6)
    a, b = _run(smollm2.complete([short, long]))
    rendered = smollm2._render(long)[0]
    assert b.prompt_tokens == len(smollm2.tokenizer(rendered, add_special_tokens=False)["input_ids"])
    assert a.prompt_tokens < b.prompt_tokens
    assert 0 < a.completion_tokens <= 6 and 0 < b.completion_tokens <= 6


def test_seeded_sampling_repeats_and_n_gives_n_texts(smollm2: Any) -> None:
    request = _ask("Name a fruit.", temperature=1.0, max_tokens=12, seed=7, n=2)
    first, second = _run(smollm2.complete([request, request]))
    assert len(first.texts) == 2 and first.texts == second.texts
    greedy = _ask("Name a fruit.", temperature=0.0, max_tokens=12)
    g1, g2 = _run(smollm2.complete([greedy])), _run(smollm2.complete([greedy]))
    assert g1[0].text == g2[0].text


def test_over_context_request_is_refused_before_generating(smollm2: Any) -> None:
    calls_before = smollm2.generate_calls
    huge = _ask("apple " * 9000, max_tokens=16)
    with pytest.raises(ContextLengthError, match=r"request 0 needs \d+ prompt \+ 16 max_tokens .* 8192"):
        _run(smollm2.complete([huge]))
    assert smollm2.generate_calls == calls_before


def test_image_for_a_text_model_is_a_clear_error(smollm2: Any) -> None:
    from PIL import Image

    request = ChatRequest(messages=[{"role": "user", "content": [
        {"type": "image", "image": Image.new("RGB", (32, 32))}, {"type": "text", "text": "what is this?"}]}])
    with pytest.raises(BackendError, match="not a vision model"):
        _run(smollm2.complete([request]))


def test_unknown_option_is_refused() -> None:
    with pytest.raises(TypeError, match="unknown options.*max_batch"):
        make_backend(load_spec("hf:smollm2-135m-instruct"), max_batch=4)


def test_tiny_qwen3_structured_output_under_the_qwen_vocabulary(tiny_qwen3: Any) -> None:
    schema = {"type": "object", "properties": {
        "verdict": {"enum": ["match", "mismatch"]}, "step": {"type": "integer", "minimum": 0, "maximum": 9},
        "note": {"type": "string", "maxLength": 12}}, "required": ["verdict", "step", "note"],
        "additionalProperties": False}
    requests = [ChatRequest(messages=[{"role": "user", "content": f"Judge step {i}."}],
                            sampling=Sampling(max_tokens=64, temperature=0.7 * (i % 2), seed=i), json_schema=schema)
                for i in range(4)]
    results = _run(tiny_qwen3.complete(requests))
    for result in results:
        value = json.loads(result.text)
        assert value["verdict"] in ("match", "mismatch") and 0 <= value["step"] <= 9 and len(value["note"]) <= 12
    assert "<think>\n\n</think>" in tiny_qwen3._render(requests[0])[0]  # enable_thinking=false from the spec
    plan = _run(tiny_qwen3.complete([ChatRequest(messages=[{"role": "user", "content": "plan"}],
                                                 sampling=Sampling(max_tokens=200), json_schema=PLAN_SCHEMA)]))
    assert plan[0].completion_tokens > 0


def test_tiny_qwen3_vl_takes_an_image() -> None:
    from PIL import Image

    backend = make_backend("hf:tiny-qwen3-vl")
    seen: list[Any] = []
    hook = backend.model.model.visual.register_forward_hook(lambda mod, args, kwargs_out: seen.append(args))
    try:
        image = Image.new("RGB", (128, 96), (200, 30, 30))
        with_image = ChatRequest(messages=[{"role": "user", "content": [
            {"type": "image", "image": image}, {"type": "text", "text": "What is in view?"}]}],
            sampling=Sampling(max_tokens=8))
        text_only = ChatRequest(messages=[{"role": "user", "content": "What is in view?"}],
                                sampling=Sampling(max_tokens=8))
        a, b = _run(backend.complete([with_image, text_only]))
        # 128x96 px -> 8x6 patches of 16 px -> merged 2x2 -> 12 image tokens + 2 vision markers
        assert a.prompt_tokens - b.prompt_tokens == 12 + 2
        assert len(seen) == 1 and a.completion_tokens > 0
    finally:
        hook.remove()
        _run(backend.aclose())


def _mixed_system_requests() -> list[ChatRequest]:
    """Two prompts under one long system message, one under another, one without any, one whose system
    message is too short to cache; greedy, so outputs can be compared token for token."""
    planner = "You plan household tasks one step at a time and answer briefly. " * 12
    judge = "You compare a predicted state with what was observed and say whether they match. " * 8
    greedy = {"max_tokens": 20}
    return [
        ChatRequest(messages=[{"role": "system", "content": planner},
                              {"role": "user", "content": "Find an apple in the kitchen."}], sampling=Sampling(**greedy)),
        ChatRequest(messages=[{"role": "system", "content": planner},
                              {"role": "user", "content": "Turn left twice, then walk forward."}],
                    sampling=Sampling(**greedy)),
        ChatRequest(messages=[{"role": "system", "content": judge},
                              {"role": "user", "content": "Predicted: door open. Observed: door closed."}],
                    sampling=Sampling(**greedy)),
        _ask("Say hello.", **greedy),
        ChatRequest(messages=[{"role": "system", "content": "Be short."},
                              {"role": "user", "content": "Count to five."}], sampling=Sampling(**greedy)),
    ]


def test_system_prefix_cache_gives_the_same_tokens_and_skips_prefill() -> None:
    """float32 so the comparison is exact: the spliced-prefix batch must decode exactly what the plain
    left-padded batch decodes, alone and batched, on first use (miss) and on reuse (hit)."""
    requests = _mixed_system_requests()

    async def outputs(prefix_cache: bool) -> tuple[list[str], Any]:
        backend = make_backend(load_spec("hf:smollm2-135m-instruct"), dtype="float32", prefix_cache=prefix_cache)
        try:
            batched = [r.texts[0] for r in await backend.complete(requests)]
            again = [r.texts[0] for r in await backend.complete(requests)]
            alone = [(await backend.complete([r]))[0].texts[0] for r in requests]
            return batched + again + alone, (backend.prefix_hits, backend.prefix_misses, backend.prefilled_tokens)
        finally:
            await backend.aclose()

    plain, (hits0, misses0, prefilled_plain) = _run(outputs(False))
    cached, (hits, misses, prefilled_cached) = _run(outputs(True))
    assert cached == plain
    assert (hits0, misses0) == (0, 0)
    assert misses == 2  # the planner and judge system prompts, each computed once
    assert hits == 7  # 3 rows in the second batch + 3 alone + the second planner row of the first batch
    assert prefilled_cached < prefilled_plain / 2


def test_prefix_cache_is_off_for_vision_specs_and_when_asked() -> None:
    for address, options in [("hf:smollm2-135m-instruct", {"prefix_cache": False}), ("hf:tiny-qwen3-vl", {})]:
        backend = make_backend(load_spec(address), **options)
        try:
            assert not backend.prefix_cache
        finally:
            _run(backend.aclose())


def test_fast_decode_attention_gives_the_same_tokens() -> None:
    """float32: the grouped-matmul decode step must pick exactly the tokens transformers' sdpa picks,
    for left-padded batches with and without spliced prefixes and for single rows."""
    requests = _mixed_system_requests()

    async def outputs(fast: bool) -> list[str]:
        backend = make_backend(load_spec("hf:smollm2-135m-instruct"), dtype="float32", fast_decode=fast)
        try:
            assert backend.fast_decode is fast
            assert (backend.model.config._attn_implementation == "sdpa") is not fast
            batched = [r.texts[0] for r in await backend.complete(requests)]
            alone = [(await backend.complete([r]))[0].texts[0] for r in requests[:2]]
            return batched + alone
        finally:
            await backend.aclose()

    assert _run(outputs(True)) == _run(outputs(False))


def test_fast_decode_is_off_for_vision_specs() -> None:
    backend = make_backend(load_spec("hf:tiny-qwen3-vl"))
    try:
        assert not backend.fast_decode
    finally:
        _run(backend.aclose())
