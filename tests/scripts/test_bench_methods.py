"""`scripts/bench_methods.py` end to end on the model-free backend: every registered method gets a row
of requests and tokens per episode by role (no timings asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_costs_of_every_registered_method_on_the_random_backend(tmp_path: Path) -> None:
    from worldmind_local.registry import METHODS

    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bench_methods.py"), "--benchmark", "eb_navigation",
         "--subsets", "base", "--limit", "1", "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=600, cwd=ROOT,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    rows = {r["method"]: r for r in result["methods"]}
    assert set(rows) == set(METHODS.names())  # the registry at run time, whatever it holds
    for row in rows.values():
        assert row["episodes"] == 1 and row["requests_per_episode"] >= 1 and row["tokens_per_episode"] > 0
    bon, simura = rows["bon"]["calls_per_episode"], rows["simura"]["calls_per_episode"]
    assert set(bon) <= {"planner", "selector"} and bon["planner"] >= 1
    assert {"encoder", "planner", "memory_update"} <= set(simura)
    steps = simura["planner"]  # SimuRA: 2 to 18 requests per planning step
    assert 2 * steps <= rows["simura"]["requests_per_episode"] <= 18 * steps
    assert (tmp_path / "run" / "results.json").is_file()
