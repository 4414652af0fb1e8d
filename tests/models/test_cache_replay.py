"""Response cache, the --cache wrapper and the replay backend: exact re-runs without the model."""

from __future__ import annotations

import asyncio
import json
import sqlite3
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

from models.base import BackendError, ChatRequest, ChatResult, ModelNotFoundError, Sampling, request_key
from models.cache import CachingBackend, ResponseCache
from models.replay_backend import ReplayBackend
from models.specs import make_backend

REPO = Path(__file__).resolve().parents[2]


def _request(text: str, **sampling: Any) -> ChatRequest:
    return ChatRequest(messages=[{"role": "user", "content": text}], sampling=Sampling(**sampling))


def _result(text: str) -> ChatResult:
    return ChatResult(texts=[text], prompt_tokens=11, completion_tokens=3, latency_s=0.25, model="m")


class EchoBackend:
    """A minimal ChatBackend for the wrapper's bookkeeping (the real-model round trip is below)."""

    name = "echo"
    model_id = "test/echo"

    def __init__(self) -> None:
        self.seen: list[list[str]] = []

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        self.seen.append([str(r.messages[0]["content"]) for r in requests])
        return [_result(f"echo {r.messages[0]['content']}") for r in requests]

    async def aclose(self) -> None:
        pass


def test_cache_round_trip_and_wal(tmp_path: Path) -> None:
    with ResponseCache(tmp_path) as cache:  # a folder means <folder>/cache.sqlite
        cache.put("k1", _result("a"), "model-x", "planner")
        got = cache.get("k1")
        assert got is not None and got.texts == ["a"] and got.cached and got.model == "model-x"
        assert (got.prompt_tokens, got.completion_tokens, got.latency_s) == (11, 3, 0.25)
        assert cache.get("absent") is None and len(cache) == 1 and "k1" in cache
        cache.put("k1", _result("b"), "model-x", "planner")  # first answer recorded wins
        assert cache.get("k1").texts == ["a"]  # type: ignore[union-attr]
        assert cache.models() == {"model-x": 1}
    mode = sqlite3.connect(tmp_path / "cache.sqlite").execute("PRAGMA journal_mode").fetchone()[0]
    assert mode == "wal"


def test_cache_is_thread_safe(tmp_path: Path) -> None:
    cache = ResponseCache(tmp_path / "c.sqlite")

    def write(worker: int) -> None:
        for i in range(50):
            cache.put(f"{worker}-{i}", _result(str(i)), "m", "judge")
            assert cache.get(f"{worker}-{i}") is not None

    threads = [threading.Thread(target=write, args=(w,)) for w in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(cache) == 200
    cache.close()


def test_caching_backend_serves_hits_and_records_misses(tmp_path: Path) -> None:
    inner = EchoBackend()
    backend = CachingBackend(inner, tmp_path / "cache.sqlite")
    first = asyncio.run(backend.complete([_request("a"), _request("b"), _request("a")]))
    assert [r.text for r in first] == ["echo a", "echo b", "echo a"]
    assert inner.seen == [["a", "b"]]  # the duplicate was asked once
    second = asyncio.run(backend.complete([_request("b"), _request("c")]))
    assert inner.seen[-1] == ["c"] and second[0].cached and not second[1].cached
    assert (backend.hits, backend.misses) == (2, 3)
    asyncio.run(backend.aclose())


def test_replay_misses_are_errors_naming_key_and_model(tmp_path: Path) -> None:
    cache = ResponseCache(tmp_path)
    known = _request("known")
    cache.put(request_key("test/echo", known), _result("recorded"), "test/echo", "planner")
    cache.close()
    replay = ReplayBackend(None, cache_path=tmp_path, model_id="test/echo")
    assert asyncio.run(replay.complete([known]))[0].text == "recorded"
    unknown = _request("never asked")
    key = request_key("test/echo", unknown)
    with pytest.raises(BackendError, match=rf"request 0 .*key {key}\) of model test/echo"):
        asyncio.run(replay.complete([unknown]))
    changed_sampling = _request("known", temperature=0.5)
    with pytest.raises(BackendError, match="no recorded response"):
        asyncio.run(replay.complete([changed_sampling]))
    asyncio.run(replay.aclose())


def test_replay_model_selection_and_missing_cache(tmp_path: Path) -> None:
    with pytest.raises(ModelNotFoundError, match="does not exist"):
        make_backend("replay", cache=tmp_path / "nothing.sqlite")
    cache = ResponseCache(tmp_path)
    cache.put("k", _result("x"), "org/model-a", "planner")
    cache.close()
    assert make_backend("replay", cache=tmp_path).model_id == "org/model-a"  # the only model recorded
    assert make_backend("replay:org/model-a", cache=tmp_path).model_id == "org/model-a"
    with pytest.raises(BackendError, match="no responses of model 'other/model'.*org/model-a"):
        make_backend("replay", cache=tmp_path, model_id="other/model")
    with pytest.raises(ValueError, match="give the recorded cache"):
        ReplayBackend(None, model_id="org/model-a")


@pytest.mark.slow
def test_replay_round_trip_with_smollm2_is_exact_and_model_free(tmp_path: Path) -> None:
    verdict = {"type": "object", "properties": {"verdict": {"enum": ["match", "mismatch"]},
               "reason": {"type": "string", "maxLength": 40}}, "required": ["verdict", "reason"],
               "additionalProperties": False}
    live = make_backend("hf:smollm2-135m-instruct", gather_window_s=0.0)
    recorder = CachingBackend(live, tmp_path / "cache.sqlite")
    requests = [
        ChatRequest(messages=[{"role": "user", "content": f"Plan step {i} to open the fridge."}],
                    sampling=Sampling(max_tokens=48, temperature=0.7 * (i % 2), seed=i),
                    json_schema=verdict if i < 2 else None, role="planner" if i < 2 else "judge")
        for i in range(3)
    ]
    recorded = asyncio.run(recorder.complete(requests))
    calls = live.generate_calls
    again = asyncio.run(recorder.complete(requests))  # every answer now comes from the file
    assert live.generate_calls == calls and all(r.cached for r in again)
    asyncio.run(recorder.aclose())

    # A fresh process replays it: same texts and token counts, and neither torch nor transformers loaded.
    payload = [{"text": r.messages[0]["content"], "temperature": r.sampling.temperature, "seed": r.sampling.seed,
                "schema": r.json_schema, "role": r.role} for r in requests]
    code = f"""
import asyncio, json, sys
from models.base import ChatRequest, Sampling
from models.specs import make_backend
items = json.loads({json.dumps(json.dumps(payload))})
reqs = [ChatRequest(messages=[{{"role": "user", "content": it["text"]}}], json_schema=it["schema"], role=it["role"],
        sampling=Sampling(max_tokens=48, temperature=it["temperature"], seed=it["seed"])) for it in items]
backend = make_backend("replay:hf:smollm2-135m-instruct", cache={str(tmp_path)!r})
out = asyncio.run(backend.complete(reqs))
assert "torch" not in sys.modules and "transformers" not in sys.modules
print(json.dumps([[r.texts, r.prompt_tokens, r.completion_tokens] for r in out]))
"""
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    replayed = json.loads(proc.stdout)
    assert replayed == [[r.texts, r.prompt_tokens, r.completion_tokens] for r in recorded]
    assert json.loads(recorded[1].text)["verdict"] in ("match", "mismatch")  # constrained answers parse
