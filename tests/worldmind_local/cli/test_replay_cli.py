"""`worldmind replay` end to end (on the generated EB-ALFRED suite, and on the data pack when present)."""

from __future__ import annotations

import io
import json

from worldmind_local.cli import main


def test_expert_replay_writes_results_and_summary(tmp_path, capsys):
    out = tmp_path / "results.jsonl"
    rc = main(["replay", "--benchmark", "eb_alfred", "--suite", "generated", "--seed", "2", "--per-subset", "3",
               "--expert", "--subsets", "base,long_horizon", "--out", str(out), "--no-progress"])
    assert rc == 0
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert len(lines) == 6 and all(r["success"] for r in lines)
    summary = capsys.readouterr().out
    assert "SR %" in summary and "long_horizon" in summary and "100.0" in summary


def test_plans_from_stdin_with_a_bad_line(monkeypatch, capsys):
    plans = "\n".join([json.dumps({"subset": "base", "index": 0, "actions": ["find a Fridge"]}), "oops"])
    monkeypatch.setattr("sys.stdin", io.StringIO(plans))
    rc = main(["replay", "--benchmark", "eb_alfred", "--suite", "generated", "--per-subset", "2", "--plans", "-", "--no-progress"])
    assert rc == 0
    captured = capsys.readouterr()
    results = [json.loads(x) for x in captured.out.splitlines()]
    assert results[0]["steps"] == 1 and "error" in results[1]
    assert "base" in captured.err  # the summary goes to stderr when results go to stdout


def test_input_errors_are_one_line_not_a_traceback(tmp_path, capsys):
    rc = main(["replay", "--benchmark", "eb_alfred", "--suite", "generated", "--plans", str(tmp_path / "missing.jsonl")])
    assert rc == 2 and "not found" in capsys.readouterr().err
    rc = main(["replay", "--benchmark", "eb_alfred", "--suite", "generated", "--expert", "--subsets", "bogus"])
    assert rc == 2 and "unknown subset" in capsys.readouterr().err
    rc = main(["replay", "--benchmark", "eb_alfred", "--data-dir", str(tmp_path), "--expert"])
    assert rc == 2 and "no eb_alfred data" in capsys.readouterr().err


def test_data_pack_expert_replay(eb_data_dir, tmp_path):
    out = tmp_path / "r.jsonl"
    rc = main(["replay", "--benchmark", "eb_alfred", "--data-dir", str(eb_data_dir), "--expert", "--subsets", "base",
               "--out", str(out), "--no-progress"])
    assert rc == 0
    lines = [json.loads(x) for x in out.read_text().splitlines()]
    assert len(lines) == 50 and all(r["success"] for r in lines)
