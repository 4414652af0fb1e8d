"""The `openai` backend: any OpenAI-compatible chat server (`vllm serve`, llama.cpp server, SGLang).

Why a backend of its own: on a cluster one `vllm serve` per GPU (or one data-parallel server) is shared by
many evaluation jobs, and the runner only has to keep enough requests in flight. So this backend is just
careful HTTP: bounded concurrency (a semaphore), requests spread over several base URLs (least-loaded,
ties in round-robin order), retries with exponential backoff and jitter on connection errors, time-outs,
429 and 5xx (a bounded number, then a `BackendError` naming the URL), structured output through
`response_format` JSON schema, and images sent as data-URL `image_url` parts.

Base URLs are the ones an OpenAI client takes (they end in `/v1`), from the `base_urls` option, the
spec's `options.base_urls` (or `options.base_url`), or the environment variable
`WORLDMIND_OPENAI_BASE_URLS` (comma- or space-separated), in that order.
"""

from __future__ import annotations

import asyncio
import base64
import io
import json
import os
import random
import re
import time
from pathlib import Path
from typing import Any

import httpx

from models.base import BackendError, ChatRequest, ChatResult, ContextLengthError
from models.specs import ModelSpec

__all__ = ["OpenAIBackend", "BASE_URLS_ENV", "resolve_base_urls", "to_openai_messages"]

BASE_URLS_ENV = "WORLDMIND_OPENAI_BASE_URLS"
_RETRY_STATUS = frozenset({408, 429, 500, 502, 503, 504})
# Phrases servers use when a prompt does not fit (vLLM, llama.cpp, SGLang, OpenAI).
_CONTEXT_PHRASES = ("context length", "context_length", "maximum context", "too long", "exceeds the context",
                    "reduce the length", "max_model_len", "context window", "exceed_context_size")


def resolve_base_urls(spec: ModelSpec, base_urls: str | list[str] | None) -> list[str]:
    """The servers to use: option, then spec option, then the environment; an error if none is given."""
    candidates: Any = base_urls or spec.options.get("base_urls") or spec.options.get("base_url")
    candidates = candidates or os.environ.get(BASE_URLS_ENV, "")
    if isinstance(candidates, str):
        candidates = re.split(r"[,\s]+", candidates)
    urls = [str(u).strip().rstrip("/") for u in candidates if str(u).strip()]
    if not urls:
        raise BackendError(
            f"openai backend for {spec.address}: no server given; pass base_urls=[...], set "
            f"options.base_urls in the spec, or set {BASE_URLS_ENV}=http://host:port/v1[,...]"
        )
    for url in urls:
        if not url.startswith(("http://", "https://")):
            raise BackendError(f"openai backend for {spec.address}: base URL {url!r} is not http(s)")
    return urls


def _image_url(image: Any) -> str:
    """A PIL image (or a file path, or a URL already) as something an `image_url` part may carry."""
    if isinstance(image, str):
        if image.startswith(("http://", "https://", "data:")):
            return image
        path = Path(image)
        if not path.is_file():
            raise BackendError(f"openai backend: image {image!r} is neither a URL nor a file")
        from PIL import Image

        image = Image.open(path)
    buffer = io.BytesIO()
    image.convert("RGB").save(buffer, format="PNG")
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def to_openai_messages(messages: Any) -> list[dict[str, Any]]:
    """Our message format (models.base.ChatRequest) in the OpenAI wire format."""
    out = []
    for message in messages:
        content = message.get("content")
        if isinstance(content, list):
            parts = []
            for part in content:
                if part.get("type") == "image":
                    parts.append({"type": "image_url", "image_url": {"url": _image_url(part["image"])}})
                else:
                    parts.append(part)
            content = parts
        out.append({**message, "content": content})
    return out


def _schema_name(request: ChatRequest) -> str:
    """OpenAI requires a name matching ^[a-zA-Z0-9_-]{1,64}$ for a json_schema response format."""
    title = str((request.json_schema or {}).get("title") or request.role or "response")
    return re.sub(r"[^a-zA-Z0-9_-]", "_", title)[:64] or "response"


class _Server:
    """One base URL and how many requests are in flight on it (for least-loaded choice)."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.in_flight = 0


class OpenAIBackend:
    """ChatBackend over OpenAI-compatible HTTP servers; see the module docstring for the policy."""

    name = "openai"

    def __init__(
        self,
        spec: ModelSpec,
        base_urls: str | list[str] | None = None,
        api_key: str | None = None,
        max_concurrency: int = 32,
        timeout: float = 300.0,
        retries: int = 4,
        backoff_s: float = 0.5,
        max_backoff_s: float = 8.0,
        served_model: str | None = None,
        seed: int | None = None,
    ) -> None:
        if max_concurrency < 1 or retries < 0 or timeout <= 0:
            raise ValueError("openai backend: max_concurrency >= 1, retries >= 0 and timeout > 0 are required")
        self.spec = spec
        self.model_id = spec.model_id
        # The name the server knows the model by (`vllm serve --served-model-name`).
        self.served_model = served_model or spec.options.get("served_model_name") or spec.model_id
        self.servers = [_Server(u) for u in resolve_base_urls(spec, base_urls)]
        self.api_key = api_key or spec.options.get("api_key") or os.environ.get("OPENAI_API_KEY")
        self.max_concurrency = max_concurrency
        self.timeout = timeout
        self.retries = retries
        self.backoff_s = backoff_s
        self.max_backoff_s = max_backoff_s
        self._rng = random.Random(seed)
        self._next = 0
        # httpx clients and asyncio semaphores belong to one event loop: made on first use per loop.
        self._loop: asyncio.AbstractEventLoop | None = None
        self._client: httpx.AsyncClient | None = None
        self._semaphore: asyncio.Semaphore | None = None

    # -- plumbing ---------------------------------------------------------------------------------

    async def _ensure_client(self) -> tuple[httpx.AsyncClient, asyncio.Semaphore]:
        loop = asyncio.get_running_loop()
        if self._client is None or self._semaphore is None or self._loop is not loop:
            if self._client is not None and self._loop is loop:
                await self._client.aclose()
            headers = {"Authorization": f"Bearer {self.api_key}"} if self.api_key else {}
            self._client = httpx.AsyncClient(
                headers=headers,
                timeout=httpx.Timeout(self.timeout, connect=min(self.timeout, 10.0)),
                limits=httpx.Limits(max_connections=self.max_concurrency),
            )
            self._semaphore = asyncio.Semaphore(self.max_concurrency)
            self._loop = loop
        return self._client, self._semaphore

    def _pick_server(self, avoid: _Server | None) -> _Server:
        """Least in flight; ties go round-robin; after a failure, prefer another server if there is one."""
        pool = [s for s in self.servers if s is not avoid] or self.servers
        start = self._next % len(pool)
        self._next += 1
        ordered = pool[start:] + pool[:start]
        return min(ordered, key=lambda s: s.in_flight)

    def _backoff(self, attempt: int) -> float:
        return min(self.max_backoff_s, self.backoff_s * 2**attempt) * (0.5 + self._rng.random())

    def payload(self, request: ChatRequest) -> dict[str, Any]:
        """The JSON body of one chat-completions call."""
        sampling = request.sampling
        body: dict[str, Any] = {
            "model": self.served_model,
            "messages": to_openai_messages(request.messages),
            "temperature": sampling.temperature,
            "top_p": sampling.top_p,
            "max_tokens": sampling.max_tokens,
            "n": sampling.n,
        }
        if sampling.seed is not None:
            body["seed"] = sampling.seed
        if request.json_schema is not None:
            body["response_format"] = {
                "type": "json_schema",
                "json_schema": {"name": _schema_name(request), "schema": request.json_schema, "strict": True},
            }
        template = {**self.spec.chat_template_kwargs, **(request.chat_template_kwargs or {})}
        if template:
            body["chat_template_kwargs"] = template  # vLLM and SGLang read it; others ignore it
        return body

    # -- one request ------------------------------------------------------------------------------

    def _parse(self, url: str, response: httpx.Response) -> tuple[list[str], int, int]:
        try:
            data = response.json()
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise BackendError(f"openai backend: {url} answered non-JSON: {response.text[:200]!r}") from exc
        choices = data.get("choices") if isinstance(data, dict) else None
        if not isinstance(choices, list) or not choices:
            raise BackendError(f"openai backend: {url} answered without choices: {str(data)[:200]!r}")
        texts = []
        for choice in sorted(choices, key=lambda c: c.get("index", 0) if isinstance(c, dict) else 0):
            content = choice.get("message", {}).get("content") if isinstance(choice, dict) else None
            if not isinstance(content, str):
                raise BackendError(f"openai backend: {url} answered a choice without text: {str(choice)[:200]!r}")
            texts.append(content)
        usage = data.get("usage") or {}
        return texts, int(usage.get("prompt_tokens") or 0), int(usage.get("completion_tokens") or 0)

    def _client_error(self, url: str, response: httpx.Response) -> BackendError:
        """A 4xx that retrying will not fix; a prompt over the context length gets its own class."""
        text = response.text[:500]
        if response.status_code in (400, 413, 422) and any(p in text.lower() for p in _CONTEXT_PHRASES):
            return ContextLengthError(f"openai backend: {url} rejected the prompt as too long: {text}")
        return BackendError(f"openai backend: {url} answered HTTP {response.status_code}: {text}")

    async def _one(self, request: ChatRequest) -> ChatResult:
        client, semaphore = await self._ensure_client()
        body = self.payload(request)
        async with semaphore:
            start = time.perf_counter()
            server: _Server | None = None
            last_error = ""
            for attempt in range(self.retries + 1):
                if attempt:
                    await asyncio.sleep(self._backoff(attempt - 1))
                server = self._pick_server(avoid=server)
                url = f"{server.url}/chat/completions"
                server.in_flight += 1
                try:
                    response = await client.post(url, json=body)
                except (httpx.TransportError, httpx.TimeoutException) as exc:
                    last_error = f"{url}: {type(exc).__name__}: {exc}"
                    continue
                finally:
                    server.in_flight -= 1
                if response.status_code in _RETRY_STATUS:
                    last_error = f"{url}: HTTP {response.status_code}: {response.text[:200]}"
                    continue
                if response.status_code >= 400:
                    raise self._client_error(url, response)
                texts, prompt_tokens, completion_tokens = self._parse(url, response)
                return ChatResult(
                    texts=texts,
                    prompt_tokens=prompt_tokens,
                    completion_tokens=completion_tokens,
                    latency_s=time.perf_counter() - start,
                    model=self.model_id,
                )
        raise BackendError(f"openai backend: gave up after {self.retries + 1} attempts; last: {last_error}")

    # -- ChatBackend ------------------------------------------------------------------------------

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        """All requests at once (the semaphore bounds what is in flight); results in request order."""
        tasks = [asyncio.ensure_future(self._one(r)) for r in requests]
        try:
            return list(await asyncio.gather(*tasks))
        except BaseException:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            raise

    async def aclose(self) -> None:
        if self._client is not None:
            await self._client.aclose()
        self._client = None
        self._semaphore = None
        self._loop = None
