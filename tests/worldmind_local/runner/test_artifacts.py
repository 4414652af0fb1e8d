from __future__ import annotations

import json
from pathlib import Path

import pytest

from worldmind_local.runner.artifacts import ManifestMismatch, RunDir


def test_torn_last_line_is_dropped(tmp_path: Path):
    sd = RunDir(tmp_path).stream("s")
    sd.ensure()
    sd.append_episode({"index": 0, "success": True})
    sd.append_episode({"index": 1, "success": False})
    with sd.episodes_path.open("a") as f:
        f.write('{"index": 2, "succ')  # killed mid-write
    records = sd.read_episodes()
    assert [r["index"] for r in records] == [0, 1]
    # the torn bytes are gone, so the next append starts on a clean line
    sd.append_episode({"index": 2})
    assert [json.loads(x)["index"] for x in sd.episodes_path.read_text().splitlines()] == [0, 1, 2]


def test_manifest_resume_and_mismatch(tmp_path: Path):
    rd = RunDir(tmp_path / "run")
    assert rd.open({"a": 1}, {"started_at": "t0"}) is False
    assert rd.open({"a": 1}, {"started_at": "t1"}) is True
    assert len(rd.read_manifest()["resumed"]) == 1
    with pytest.raises(ManifestMismatch, match="differs in: a"):
        rd.open({"a": 2}, {})
