"""`worldmind replay --plans` with hostile lines (issue 18, points 5 and 6): each bad line becomes an
error line naming its number; the run goes on."""

from __future__ import annotations

import json
from pathlib import Path

from worldmind_local.cli import main


def test_non_utf8_deep_and_huge_lines_become_error_lines(tmp_path: Path) -> None:
    good = json.dumps({"subset": "base", "index": 0, "actions": ["find a Fridge"]}).encode()
    plans = tmp_path / "plans.jsonl"
    plans.write_bytes(b"\n".join([
        b'{"subset": "base", "index": 0, "actions": ["\xff\xfe"]}',
        b"[" * 50_000,
        b'{"subset": "base", "index": ' + b"9" * 5000 + b', "actions": []}',
        b'{"subset": "base", "index": 0, "actions": [NaN]}',
        good,
    ]))
    out = tmp_path / "out.jsonl"
    rc = main(["replay", "--benchmark", "eb_alfred", "--suite", "generated", "--per-subset", "2",
               "--plans", str(plans), "--out", str(out), "--no-progress"])
    assert rc == 0
    results = [json.loads(x) for x in out.read_text().splitlines()]
    assert [r.get("line") for r in results[:4]] == [1, 2, 3, 4]
    assert "not UTF-8" in results[0]["error"] and all("error" in r for r in results[:4])
    assert results[4]["steps"] == 1 and "error" not in results[4]
