"""`worldmind report` over real runs (random:seeded-random): every table in md, latex, csv and html, every
figure, and the numbers checked against values computed here from episodes.jsonl."""

from __future__ import annotations

import csv
import json
import math
import statistics
from pathlib import Path

import pytest

from worldmind_local.cli import main

pytestmark = pytest.mark.slow
Z = 1.959963984540054


def _episodes(run: Path, stream_id: str) -> list[dict]:
    return [json.loads(x) for x in (run / "streams" / stream_id / "episodes.jsonl").read_text().splitlines()]


def _csv(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(path.open()))


@pytest.fixture(scope="module")
def report(real_runs, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("report")
    runs = [str(real_runs[k]) for k in ("runA", "runB", "runC")]
    assert main(["report", *runs, "--format", "md,latex,csv,html", "--out", str(out)]) == 0
    return out


def test_every_table_in_every_format(report: Path) -> None:
    want = {"main_eb_alfred", "memory_budget_eb_alfred_seeded-random_worldmind", "transfer", "robustness",
            "task_order", "taxonomy", "overhead", "comparisons", "streams"}
    keys = {p.stem for p in (report / "csv").glob("*.csv")}
    assert want <= keys
    md, tex = (report / "tables.md").read_text(), (report / "tables.tex").read_text()
    index = (report / "site" / "index.html").read_text()
    for key in keys:
        assert f'id="{key}"' in index and f"tab:{key.replace('_', chr(92) + '_')}" in tex
    assert md.count("### ") == len(keys) and "symbolic twin (not the real simulator)" in md
    for name in ("bars_eb_alfred", "learning_eb_alfred", "taxonomy", "transfer_heatmap",
                 "memory_budget_eb_alfred_seeded-random_worldmind"):
        assert (report / "figures" / f"{name}.png").stat().st_size > 1000
        assert (report / "figures" / f"{name}.svg").read_text().lstrip().startswith("<?xml")


def test_main_table_equals_an_independent_computation(report: Path, real_runs) -> None:
    from tests.worldmind_local.reporting.conftest import _spec

    rows = {r["Method"]: r for r in _csv(report / "csv" / "main_eb_alfred.csv")}
    for method in ("worldmind", "react"):
        for subset, col in (("base", "Base"), ("common_sense", "Common")):
            for metric, fn in (("SR", lambda r: 100.0 * r["success"]), ("GC", lambda r: 100.0 * r["progress"])):
                per_seed = [statistics.mean(fn(r) for r in _episodes(real_runs[run], _spec(subset, method, seed).stream_id))
                            for run, seed in (("runA", 0), ("runB", 1))]
                assert float(rows[method][f"{metric} {col}"]) == pytest.approx(statistics.mean(per_seed), abs=0.01)
                assert float(rows[method][f"{metric} {col}_sd"]) == pytest.approx(statistics.stdev(per_seed), abs=0.01)
        assert rows[method]["Seeds"] == "2" and rows[method]["Episodes"] == "12"


def test_stream_intervals_are_wilson(report: Path, real_runs) -> None:
    for row in _csv(report / "csv" / "streams.csv"):
        recs = _episodes(real_runs[row["Run"]], row["Stream"])
        k, n = sum(r["success"] for r in recs), len(recs)
        p = k / n
        centre = (p + Z * Z / (2 * n)) / (1 + Z * Z / n)
        half = Z * math.sqrt(p * (1 - p) / n + Z * Z / (4 * n * n)) / (1 + Z * Z / n)
        assert float(row["SR [Wilson 95%]_lo"]) == pytest.approx(100 * (centre - half), abs=0.01)
        assert float(row["SR [Wilson 95%]_hi"]) == pytest.approx(100 * (centre + half), abs=0.01)


def test_taxonomy_overhead_and_stress_tables(report: Path, real_runs) -> None:
    from tests.worldmind_local.reporting.conftest import _spec

    tax = {r["Method"]: r for r in _csv(report / "csv" / "taxonomy.csv")}
    recs = [r for run, seed in (("runA", 0), ("runB", 1)) for sub in ("base", "common_sense")
            for r in _episodes(real_runs[run], _spec(sub, "worldmind", seed).stream_id)]
    for key, col in (("invalid_action_end", "Invalid-action end"), ("step_limit", "Step limit"),
                     ("wrong_termination", "Wrong termination")):
        assert int(tax["worldmind"][col]) == sum(r["taxonomy"] == key for r in recs)
    over = [r for r in _csv(report / "csv" / "overhead.csv") if r["Method"] == "worldmind"]
    calls = next(r for r in over if r["Metric"] == "Model calls per episode")
    base = [r for run, seed in (("runA", 0), ("runB", 1))
            for r in _episodes(real_runs[run], _spec("base", "worldmind", seed).stream_id)]
    assert float(calls["Base"]) == pytest.approx(sum(len(r["calls"]) for r in base) / len(base), abs=0.01)
    rob = _csv(report / "csv" / "robustness.csv")
    assert {r["Perturbation"] for r in rob} >= {"clean", "object rename (synonyms)", "memory poison (20% corrupted)"}
    order = _csv(report / "csv" / "task_order.csv")
    assert {"Order seed 1", "Order seed 2", "Original order"} <= set(order[0])
    budget = [r["Memory Setting"] for r in _csv(report / "csv" / "memory_budget_eb_alfred_seeded-random_worldmind.csv")]
    assert {"Mem0 (top-2)", "Mem10 (top-2)", "Mem30 (top-2)", "Mem30 (top-3)"} <= set(budget)
    poison = json.loads(next((real_runs["runC"] / "streams").glob("*/poison.json")).read_text())
    assert poison["poisoned"] == math.floor(0.2 * poison["entries"] + 0.5)


def test_markdown_to_stdout(real_runs, capsys) -> None:
    assert main(["report", str(real_runs["runA"])]) == 0
    out = capsys.readouterr().out
    assert "### Main results on eb_alfred" in out and "### Paired comparisons of methods" in out
