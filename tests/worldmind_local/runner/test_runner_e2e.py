"""The runner's promises, end to end on the EB-ALFRED twin with the seeded-random backend (deterministic,
model-free) and the real all-MiniLM embedder:

- a stream's episodes.jsonl and memory are identical whether it runs alone or among 8 others;
- SIGKILL mid-run then re-run: no finished episode lost or repeated, memory == memory of the episodes on disk;
- a stream that raises is recorded as failed and the others finish.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from worldmind_local.runner import RunConfig, StreamSpec, run_experiment

RANDOM = "random:seeded-random"
VOLATILE = ("latency", "seconds", "_ms", "time")


def _strip(obj):
    if isinstance(obj, dict):
        return {k: _strip(v) for k, v in obj.items() if not any(t in k for t in VOLATILE)}
    if isinstance(obj, list):
        return [_strip(v) for v in obj]
    return obj


def _episodes(run: Path, stream_id: str) -> list[dict]:
    lines = (run / "streams" / stream_id / "episodes.jsonl").read_text().splitlines()
    return [_strip(json.loads(x)) for x in lines]


def _memory_rows(run: Path, stream_id: str) -> list[dict]:
    import datasets

    ds = datasets.load_from_disk(str(run / "streams" / stream_id / "memory"))
    rows = ds if isinstance(ds, datasets.Dataset) else datasets.concatenate_datasets(list(ds.values()))
    return sorted((dict(r) for r in rows), key=lambda r: (r["partition"], r["id"]))


@pytest.fixture(scope="module")
def embedder():
    from worldmind_local.memory import Embedder

    return Embedder()


def _spec(subset: str, seed: int = 0, **opts) -> StreamSpec:
    return StreamSpec(benchmark="eb_alfred", subset=subset, planner=RANDOM, seed=seed, limit=3,
                      options=dict(opts))


def _run(streams, out: Path, embedder, **kw):
    config = RunConfig(streams=streams, suite="generated", suite_size=3, **kw)
    return asyncio.run(run_experiment(config, out, embedder=embedder, progress=False))


@pytest.mark.slow
def test_stream_alone_equals_stream_among_eight(tmp_path: Path, embedder):
    target = _spec("base")
    others = [_spec(s, seed) for s in ("common_sense", "spatial", "visual_appearance", "complex_instruction")
              for seed in (1, 2)]
    # The run id (the folder's name) is part of every entry's provenance, so both runs share it.
    alone_dir, crowd_dir = tmp_path / "alone" / "run", tmp_path / "crowd" / "run"
    alone = _run([target], alone_dir, embedder)
    crowd = _run([*others[:4], target, *others[4:]], crowd_dir, embedder)
    assert not alone.failed and not crowd.failed
    sid = target.stream_id
    assert _episodes(alone_dir, sid) == _episodes(crowd_dir, sid)
    assert _memory_rows(alone_dir, sid) == _memory_rows(crowd_dir, sid)
    assert len(_episodes(alone_dir, sid)) == 3
    # the random planner exercises the judge, the reflector and the memory, so the comparison has teeth
    assert sum(e["method_stats"]["judge_calls"] for e in _episodes(alone_dir, sid)) > 0


@pytest.mark.slow
def test_wave_is_deterministic(tmp_path: Path, embedder):
    s = _spec("base")
    a = _run([s], tmp_path / "a" / "run", embedder, wave=3)
    _run([s], tmp_path / "b" / "run", embedder, wave=3)
    assert not a.failed
    assert _episodes(tmp_path / "a" / "run", s.stream_id) == _episodes(tmp_path / "b" / "run", s.stream_id)


@pytest.mark.slow
def test_failing_stream_does_not_stop_others(tmp_path: Path, embedder):
    good = _spec("base")
    broken = tmp_path / "broken-memory"  # looks like a saved dataset, but cannot be read
    broken.mkdir()
    (broken / "dataset_info.json").write_text("{not json")
    (broken / "state.json").write_text("{not json")
    bad = StreamSpec(benchmark="eb_alfred", subset="spatial", planner=RANDOM, limit=2, memory_from=str(broken))
    res = _run([bad, good], tmp_path / "run", embedder)
    status = {o.stream_id: o.status for o in res.outcomes}
    assert status[good.stream_id] == "finished"
    assert status[bad.stream_id] == "failed"
    failed = [s for s in res.results["streams"] if s["status"] == "failed"]
    assert failed and failed[0]["error"]
    # a memory source that does not exist is refused before the run folder is even created
    missing = StreamSpec(benchmark="eb_alfred", subset="spatial", planner=RANDOM, limit=2,
                         memory_from=str(tmp_path / "no-such-memory"))
    with pytest.raises(FileNotFoundError, match="no such folder"):
        _run([missing, good], tmp_path / "never", embedder)
    assert not (tmp_path / "never").exists()


@pytest.mark.slow
def test_sigkill_then_resume_loses_and_repeats_nothing(tmp_path: Path):
    specs = tmp_path / "specs"
    specs.mkdir()
    (specs / "slow.yaml").write_text(
        "name: slow-random\nbackend: random\nmodel_id: seeded-random\nweights: {}\n"
        "options: {latency_s: 0.05}\n"
    )
    env = {**os.environ, "WORLDMIND_MODEL_SPECS": str(specs)}
    out = tmp_path / "killed" / "run"
    cmd = [sys.executable, "-m", "worldmind_local.cli", "run", "--benchmark", "eb_alfred", "--subsets", "base",
           "--suite", "generated", "--suite-size", "8", "--planner", "random:slow-random",
           "--out", str(out), "--progress", "lines"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    episodes = out / "streams" / "eb_alfred.base.worldmind.slow-random.s0" / "episodes.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline:
        if episodes.exists() and len(episodes.read_text().splitlines()) >= 2:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    n_before = len(episodes.read_text().splitlines())
    assert 2 <= n_before < 8, "the run finished before it could be killed; raise latency_s"
    before = episodes.read_text().splitlines()
    resumed = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    after = episodes.read_text().splitlines()
    assert after[:n_before] == before  # nothing lost or rewritten
    assert [json.loads(x)["index"] for x in after] == list(range(8))  # nothing repeated

    # An uninterrupted run gives the same episodes and the same memory.
    ref = tmp_path / "ref" / "run"  # same run id (folder name): it is part of the provenance
    ref_cmd = [c if c != str(out) else str(ref) for c in cmd]
    done = subprocess.run(ref_cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    sid = "eb_alfred.base.worldmind.slow-random.s0"
    assert _episodes(out, sid) == _episodes(ref, sid)
    assert _memory_rows(out, sid) == _memory_rows(ref, sid)
    # and the memory on disk is exactly the experience recorded in episodes.jsonl
    kept = sorted(e["id"] for line in after for e in json.loads(line).get("experience", []) if e["kept"])
    assert sorted(r["id"] for r in _memory_rows(out, sid)) == kept


def _drop_last_lines(run: Path, stream_id: str, n: int) -> None:
    path = run / "streams" / stream_id / "episodes.jsonl"
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:-n]))


@pytest.mark.slow
def test_kill_after_the_memory_save_before_the_line_resumes_exactly(tmp_path: Path, embedder):
    """The runner saves memory/ before it appends the episode line; a kill in between leaves a memory one
    commit ahead, which resume cuts back to the recorded episodes (no embeddings in episodes.jsonl)."""
    s = _spec("base")
    ref, cut = tmp_path / "ref" / "run", tmp_path / "cut" / "run"
    _run([s], ref, embedder)
    _run([s], cut, embedder)
    assert all("key_embedding" not in e for line in _episodes(cut, s.stream_id) for e in line["experience"])
    _drop_last_lines(cut, s.stream_id, 1)
    _run([s], cut, embedder)
    assert _episodes(cut, s.stream_id) == _episodes(ref, s.stream_id)
    assert _memory_rows(cut, s.stream_id) == _memory_rows(ref, s.stream_id)


@pytest.mark.slow
def test_a_partly_written_wave_is_rolled_back_and_rerun(tmp_path: Path, embedder):
    s = _spec("base")
    ref, cut = tmp_path / "ref" / "run", tmp_path / "cut" / "run"
    _run([s], ref, embedder, wave=3)
    _run([s], cut, embedder, wave=3)
    _drop_last_lines(cut, s.stream_id, 2)  # one line of the wave of three survived
    _run([s], cut, embedder, wave=3)
    assert _episodes(cut, s.stream_id) == _episodes(ref, s.stream_id)
    assert _memory_rows(cut, s.stream_id) == _memory_rows(ref, s.stream_id)


@pytest.mark.slow
def test_a_damaged_middle_line_is_quarantined_and_only_that_episode_reruns(tmp_path: Path, embedder):
    """Intact later records are never dropped: the damaged episode re-runs alone, on the memory as it
    stood before it, and the stream ends equal to an uninterrupted one."""
    s = _spec("base")
    ref, hurt = tmp_path / "ref" / "run", tmp_path / "hurt" / "run"
    _run([s], ref, embedder)
    _run([s], hurt, embedder)
    path = hurt / "streams" / s.stream_id / "episodes.jsonl"
    lines = path.read_bytes().splitlines(keepends=True)
    later = [json.loads(x)["index"] for x in lines[2:]]
    path.write_bytes(lines[0] + b'{"index": 1, "broken\n' + b"".join(lines[2:]))
    res = _run([s], hurt, embedder)
    assert [o.ran_episodes for o in res.outcomes] == [1]  # only the damaged one
    assert (path.parent / "episodes.quarantine.jsonl").exists()
    assert _episodes(hurt, s.stream_id) == _episodes(ref, s.stream_id)
    assert _memory_rows(hurt, s.stream_id) == _memory_rows(ref, s.stream_id)
    assert later == [2]
