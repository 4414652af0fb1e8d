"""`worldmind transfer`: 2 planners x 2 benchmarks with the model-free backend. The full matrix runs as
concurrent streams, seeded streams wait for their sources, a SIGKILL mid-run resumes to the same
matrix, and the table separates every seeded row from its from-scratch row."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from worldmind_local.cli import main
from worldmind_local.memory.sources import open_source

BENCHMARKS = ("eb_alfred", "eb_navigation")
PLANNERS = ("random:slow-a", "random:slow-b")


@pytest.fixture
def specs(tmp_path, monkeypatch) -> dict[str, str]:
    folder = tmp_path / "specs"
    folder.mkdir()
    for name in ("a", "b"):   # two "models": the seeded-random backend under two names
        (folder / f"slow-{name}.yaml").write_text(
            f"name: slow-{name}\nbackend: random\nmodel_id: seeded-random-{name}\nweights: {{}}\n"
            "options: {latency_s: 0.02}\n")
    monkeypatch.setenv("WORLDMIND_MODEL_SPECS", str(folder))
    return {**os.environ, "WORLDMIND_MODEL_SPECS": str(folder)}


def _argv(out: Path) -> list[str]:
    return ["transfer", "--benchmark", ",".join(BENCHMARKS), "--planners", ",".join(PLANNERS),
            "--memory-benchmarks", ",".join(BENCHMARKS), "--suite", "generated", "--suite-size", "3",
            "--progress", "lines", "--out", str(out)]


def test_plan_file_builds_the_same_matrix(specs, tmp_path):
    from worldmind_local.cli import build_parser
    from worldmind_local.cli.transfer import build_config

    plan = tmp_path / "transfer.yaml"
    plan.write_text("transfer:\n  benchmarks: [eb_alfred, eb_navigation]\n  planners: [random:slow-a, random:slow-b]\n"
                    "  memory_benchmarks: [eb_alfred, eb_navigation]\nrun: {suite: generated, suite_size: 3}\n"
                    f"out: {tmp_path / 'x'}\n")
    by_flags, _ = build_config(build_parser().parse_args(_argv(tmp_path / "x")))
    by_file, out = build_config(build_parser().parse_args(["transfer", "--plan", str(plan)]))
    assert [s.stream_id for s in by_file.streams] == [s.stream_id for s in by_flags.streams]
    assert out == str(tmp_path / "x") and by_file.suite_size == 3
    scratch = [s for s in by_flags.streams if not s.memory_from]
    seeded = [s for s in by_flags.streams if s.memory_from]
    assert len(scratch) == 4 and len(seeded) == 16
    assert {s.seed_stream for s in seeded} == {s.stream_id for s in scratch}


def test_bad_matrix_is_one_line(specs, tmp_path, capsys):
    assert main([*_argv(tmp_path / "y"), "--subsets", "spatial"]) == 2
    err = capsys.readouterr().err
    assert "unknown subset(s) spatial for eb_navigation" in err and not (tmp_path / "y").exists()


@pytest.mark.slow
def test_transfer_matrix_resumes_after_sigkill(specs, tmp_path):
    out = tmp_path / "transfer"
    cmd = [sys.executable, "-m", "worldmind_local.cli", *_argv(out)]
    proc = subprocess.Popen(cmd, env=specs, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    seeded_started = False
    while time.time() < deadline and proc.poll() is None:
        lines = [p for p in out.glob("streams/*.*.*.*.s0.*/episodes.jsonl") if p.read_text().strip()]
        if lines:
            seeded_started = True
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert seeded_started, "no seeded stream had started before the deadline"
    assert not (out / "results.json").exists(), "the run finished before it could be killed"
    done = subprocess.run(cmd, env=specs, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]

    results = json.loads((out / "results.json").read_text())
    streams = {s["stream_id"]: s for s in results["streams"]}
    assert len(streams) == 20 and all(s["status"] == "finished" for s in streams.values())
    assert all(s["metrics"]["episodes"] == 3 for s in streams.values())
    # every seeded stream started from its source's complete, final memory
    for sid, facts in results["memory_sources"].items():
        source_id = streams[sid]["memory_from"].removeprefix("stream:")
        source, _ = open_source(str(out / "streams" / source_id / "memory"))
        assert facts["sha256"] == source.sha256 and facts["entries"] == source.entries
        assert facts["provenance"]["stream_id"] == source_id
    assert len(results["memory_sources"]) == 16
    # the table: per (benchmark, planner) one from-scratch row and one row per source, each with its gain
    for bench in BENCHMARKS:
        for planner in PLANNERS:
            rows = [r for r in results["table"] if r["benchmark"] == bench and r["planner"] == planner]
            scratch = [r for r in rows if r["memory_from"] is None]
            seeded = [r for r in rows if r["memory_from"]]
            assert len(scratch) == 1 and len(seeded) == 4
            assert len({r["memory_from"] for r in seeded}) == 4
            for r in seeded:
                assert r["gain"] == {m: round(r["avg"][m] - scratch[0]["avg"][m], 2) for m in ("SR", "GC")}
    assert "memory_from" in done.stdout and "dSR:avg" in done.stdout
    assert "seeded-random-b/eb_navigation#" in done.stdout
