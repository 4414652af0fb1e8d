from __future__ import annotations

from worldmind_local.metrics import bootstrap_ci, stream_metrics, summarize_run


def test_sr_gc_and_taxonomy():
    recs = [
        {"success": True, "progress": 1.0, "taxonomy": "success", "steps": 5},
        {"success": False, "progress": 0.5, "taxonomy": "step_limit", "steps": 30},
        {"success": False, "progress": 0.0, "taxonomy": "invalid_action_end", "steps": 12},
        {"success": False, "progress": 1 / 3, "taxonomy": "wrong_termination", "steps": 3},
    ]
    m = stream_metrics(recs)
    assert m["SR"] == 25.0
    assert abs(m["GC"] - 100 * (1 + 0.5 + 1 / 3) / 4) < 0.01
    assert m["taxonomy"]["step_limit"] == 1 and m["taxonomy"]["error"] == 0
    lo, hi = m["SR_ci95"]
    assert 0 <= lo <= 25.0 <= hi <= 100


def test_bootstrap_is_deterministic_and_degenerate_cases():
    vals = [0, 100, 100, 0, 100]
    assert bootstrap_ci(vals) == bootstrap_ci(vals)
    assert bootstrap_ci([100.0, 100.0]) == (100.0, 100.0)


def test_table_average_over_subsets():
    spec = {"benchmark": "eb_alfred", "method": "worldmind", "planner": "hf:m", "judge": None, "seed": 0,
            "options": {}, "memory_budget": None, "memory_from": None}
    res = summarize_run([
        {"stream_id": "a", "spec": {**spec, "subset": "base"}, "records": [{"success": True, "progress": 1}]},
        {"stream_id": "b", "spec": {**spec, "subset": "spatial"}, "records": [{"success": False, "progress": 0}]},
    ])
    (row,) = res["table"]
    assert row["avg"] == {"SR": 50.0, "GC": 50.0}
    assert set(row["subsets"]) == {"base", "spatial"}
