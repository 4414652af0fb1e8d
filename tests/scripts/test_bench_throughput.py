"""`scripts/bench_throughput.py` end to end on the model-free backend: both modes run the same streams
and the last line is the JSON object issue 5 specifies."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
KEYS = {"backend", "model", "streams", "episodes", "episodes_per_hour_sequential", "episodes_per_hour_streams",
        "ratio", "engine_tokens_per_s", "suite_tokens_per_s", "outside_model_share"}


@pytest.mark.slow
def test_last_line_is_the_result_object() -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bench_throughput.py"), "--backend", "random", "--model",
         "seeded-random", "--streams", "3", "--episodes", "2", "--benchmark", "eb_navigation"],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert KEYS <= result.keys()
    assert (result["backend"], result["model"], result["streams"], result["episodes"]) == \
        ("random", "seeded-random", 3, 6)
    assert result["ratio"] == pytest.approx(
        result["episodes_per_hour_streams"] / result["episodes_per_hour_sequential"], rel=0.02)
    assert 0.0 <= result["outside_model_share"] <= 1.0
    assert result["calls"]["sequential"] > 0
    # a deterministic backend: both modes run the very same episodes
    assert result["calls"]["sequential"] == result["calls"]["streams"]
    assert result["sequential_tokens"] == result["streams_tokens"]
    assert result["wall_s"]["total"] >= result["wall_s"]["sequential"] + result["wall_s"]["streams"]
    assert "warm-up" in done.stderr and "(a) sequential: 6 episodes" in done.stderr
