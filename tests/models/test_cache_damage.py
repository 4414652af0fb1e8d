"""A damaged response cache (issue 18, point 4) and the requests recorded next to the responses."""

from __future__ import annotations

import asyncio
import logging
import sqlite3
from pathlib import Path

import pytest
from PIL import Image

from models.base import ChatRequest, ChatResult, Sampling, request_key
from models.cache import CachingBackend, ReplayCacheError, ResponseCache
from models.replay_backend import ReplayBackend
from worldmind_local.cli import main


def _result(text: str) -> ChatResult:
    return ChatResult(texts=[text], prompt_tokens=5, completion_tokens=2, latency_s=0.1, model="m")


def _recorded(path: Path) -> None:
    with ResponseCache(path) as cache:
        for i in range(200):
            cache.put(f"k{i}", _result("x" * 500), "org/model", "planner")


def _garbage(path: Path) -> None:
    path.write_bytes(b"this is not a database at all\n" * 100)


def _malformed(path: Path) -> None:
    """A real sqlite file whose table pages are overwritten (header intact)."""
    _recorded(path)
    data = bytearray(path.read_bytes())
    for offset in range(4096 + 100, min(len(data), 4096 * 6), 7):
        data[offset] = 0xA5
    path.write_bytes(bytes(data))
    for side in ("-wal", "-shm"):
        Path(str(path) + side).unlink(missing_ok=True)


@pytest.mark.parametrize("damage", [_garbage, _malformed])
def test_a_damaged_cache_is_moved_aside_and_the_run_goes_on(tmp_path: Path, damage, caplog) -> None:
    path = tmp_path / "cache.sqlite"
    damage(path)
    original = path.read_bytes()
    with caplog.at_level(logging.WARNING, logger="models.cache"):
        cache = ResponseCache(tmp_path)
    aside = sorted(tmp_path.glob("cache.sqlite.corrupt-*"))
    assert [p.read_bytes() for p in aside if not p.name.endswith("-wal")] == [original]
    assert len(cache) == 0
    cache.put("k", _result("fresh"), "org/model", "judge")
    assert cache.get("k").texts == ["fresh"]  # type: ignore[union-attr]
    cache.close()
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "damaged" in warnings[0] and "moved aside" in warnings[0]


@pytest.mark.parametrize("damage", [_garbage, _malformed])
def test_replay_of_a_damaged_cache_is_one_clear_error(tmp_path: Path, damage) -> None:
    path = tmp_path / "cache.sqlite"
    damage(path)
    before = path.read_bytes()
    with pytest.raises(ReplayCacheError, match=rf"{path} is damaged \(.+\)"):
        ReplayBackend(None, cache_path=tmp_path, model_id="org/model")
    assert path.read_bytes() == before and not list(tmp_path.glob("*.corrupt-*"))  # never moved aside


def test_replay_cache_error_is_one_line_in_the_cli(tmp_path: Path, capsys, monkeypatch) -> None:
    _garbage(tmp_path / "cache.sqlite")
    monkeypatch.setenv("WORLDMIND_REPLAY_CACHE", str(tmp_path))
    rc = main(["run", "--planner", "replay:org/model", "--benchmark", "eb_navigation", "--suite", "generated",
               "--limit", "1", "--subsets", "base", "--out", str(tmp_path / "run"), "--progress", "lines"])
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if ": error:" in line]
    assert rc == 2 and len(errors) == 1 and "is damaged" in errors[0] and "Traceback" not in err, err


def test_damage_found_mid_run_stops_caching_without_failing_streams(tmp_path: Path, caplog) -> None:
    cache = ResponseCache(tmp_path)
    err = sqlite3.DatabaseError("database disk image is malformed")
    err.sqlite_errorcode = 11  # type: ignore[attr-defined]

    class Broken:
        def execute(self, *a, **k):
            raise err

        executemany = execute

        def close(self) -> None:
            pass

    real, cache._db = cache._db, Broken()  # type: ignore[assignment]
    with caplog.at_level(logging.WARNING, logger="models.cache"):
        assert cache.get_many(["a"]) == {}
        cache.put("a", _result("x"), "m")
        assert cache.get("a") is None
    assert sum("unreadable" in r.getMessage() for r in caplog.records) == 1
    real.close()


def test_requests_are_recorded_next_to_responses(tmp_path: Path) -> None:
    class Echo:
        name, model_id = "echo", "test/echo"

        async def complete(self, requests):
            return [_result("ok") for _ in requests]

        async def aclose(self) -> None:
            pass

    image = Image.new("RGB", (4, 3), (255, 0, 0))
    request = ChatRequest(
        messages=[{"role": "system", "content": "be brief"},
                  {"role": "user", "content": [{"type": "text", "text": "what is this?"},
                                               {"type": "image", "image": image}]}],
        sampling=Sampling(temperature=0.5, max_tokens=7, seed=3),
        json_schema={"type": "object"}, role="judge",
    )
    backend = CachingBackend(Echo(), tmp_path)
    asyncio.run(backend.complete([request]))
    key = request_key("test/echo", request)
    stored = backend.cache.get_request(key)
    assert stored is not None
    assert stored["role"] == "judge" and stored["json_schema"] == {"type": "object"}
    assert stored["sampling"] == {"temperature": 0.5, "max_tokens": 7, "top_p": 1.0, "n": 1, "seed": 3}
    part = stored["messages"][1]["content"][1]
    assert part["type"] == "image" and len(part["sha256"]) == 64 and "image" not in part
    assert stored["messages"][0] == {"role": "system", "content": "be brief"}
    assert backend.cache.keys(role="judge") == [key] and backend.cache.keys(model="other") == []
    assert backend.cache.get_request("absent") is None
    backend.cache.put(key, _result("later"), "test/echo", "planner",
                      request=ChatRequest(messages=[{"role": "user", "content": "different"}]))
    assert backend.cache.get_request(key) == stored  # first write wins
    asyncio.run(backend.aclose())
