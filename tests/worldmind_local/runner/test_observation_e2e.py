"""What the planner is shown, end to end through the runner: EB's language-only protocol by default for
text planners on EB-ALFRED and EB-Habitat, the labelled `symbolic` option, EB-Navigation's text stand-in,
and the record of which was used (episodes, results.json, manifest.json). Prompts are read back from the
run's cache, as `worldmind show` does."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

import pytest

from models.cache import ResponseCache
from worldmind_local.runner import RunConfig, StreamSpec, run_experiment

RANDOM = "random:seeded-random"


def _run(tmp_path: Path, benchmark: str, **options) -> tuple[Path, str]:
    spec = StreamSpec(benchmark=benchmark, subset="base", planner=RANDOM, limit=1, options=options)
    out = tmp_path / f"{benchmark}-{options.get('observation', 'default')}"
    config = RunConfig(streams=[spec], suite="generated", suite_size=1)
    result = asyncio.run(run_experiment(config, out, embedder=_embedder(), progress=False))
    assert not result.failed
    return out, spec.stream_id


_EMB = None


def _embedder():
    global _EMB
    if _EMB is None:
        from worldmind_local.memory import Embedder

        _EMB = Embedder()
    return _EMB


def _planner_prompts(out: Path, stream_id: str) -> list[str]:
    record = json.loads((out / "streams" / stream_id / "episodes.jsonl").read_text().splitlines()[0])
    texts = []
    with ResponseCache(out / "cache.sqlite", create=False) as cache:
        for call in record["calls"]:
            if call["role"] == "planner":
                request = cache.get_request(call["request"])
                assert request is not None
                texts.append("\n".join(str(m["content"]) for m in request["messages"]))
    return texts


def _abstract_state(out: Path, stream_id: str) -> str:
    record = json.loads((out / "streams" / stream_id / "episodes.jsonl").read_text().splitlines()[0])
    states = [s["actual_state"] for s in record["trajectory"] if s.get("actual_state")]
    return states[0] if states else ""


@pytest.mark.parametrize("benchmark", ["eb_alfred", "eb_habitat"])
def test_text_planner_sees_no_state_by_default_and_the_state_when_asked(tmp_path: Path, benchmark: str) -> None:
    out, sid = _run(tmp_path, benchmark)
    prompts = _planner_prompts(out, sid)
    assert prompts and all("What you observe now" not in p for p in prompts)
    state = _abstract_state(out, sid)
    if state:  # the judge did see the abstract state; the planner never did
        first_line = state.splitlines()[0]
        assert all(first_line not in p for p in prompts)
    results = json.loads((out / "results.json").read_text())
    assert results["streams"][0]["metrics"]["observation"] == ["none"]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["protocol"][sid]["observation_requested"] == "auto"
    assert manifest["protocol"][sid]["actual_state"].startswith("twin_symbolic_state")

    out, sid = _run(tmp_path, benchmark, observation="symbolic")
    prompts = _planner_prompts(out, sid)
    assert all("What you observe now" in p for p in prompts)
    assert json.loads((out / "results.json").read_text())["streams"][0]["metrics"]["observation"] == ["symbolic"]


def test_navigation_text_planner_gets_the_text_description(tmp_path: Path) -> None:
    out, sid = _run(tmp_path, "eb_navigation")
    prompts = _planner_prompts(out, sid)
    assert all("What you observe now" in p for p in prompts)
    assert "Camera:" in prompts[0]  # the description always ends with the camera tilt
    assert json.loads((out / "results.json").read_text())["streams"][0]["metrics"]["observation"] == ["description"]
