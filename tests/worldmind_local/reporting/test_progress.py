"""One overall progress line/bar for many streams; per-stream lines only on request; no loading bars."""

from __future__ import annotations

import os
import sys

from worldmind_local.runner.progress import Progress, quiet_model_loading


def _records(n: int, success_every: int = 2):
    return [{"index": i, "success": i % success_every == 0, "progress": 1.0} for i in range(n)]


def test_plain_overall_lines_not_one_per_stream(capsys) -> None:
    p = Progress(enabled=False)
    bars = [p.add(f"stream-{k}", total=3) for k in range(10)]
    bars[0].skip(3)                      # resumed: done, not throughput
    for bar in bars[1:]:
        for rec in _records(3):
            bar.update(rec)
    p.close()
    err = capsys.readouterr().err.splitlines()
    assert all(line.startswith("progress: ") for line in err)
    assert len(err) <= 3                 # the first, maybe one timed, and the last: not 27 episode lines
    assert err[-1].startswith("progress: 30/30 episodes (100%)") and "streams finished 10/10" in err[-1]
    assert "successes 18/27" in err[-1] and "ETA 0s" in err[-1]


def test_per_stream_detail_on_request(capsys) -> None:
    p = Progress(enabled="streams")
    if p.tty:  # a terminal would draw bars; this test is about the plain form
        return
    bar = p.add("s", total=2)
    for rec in _records(2):
        bar.update(rec)
    err = capsys.readouterr().err
    assert err.count("[s] episode") == 2 and "progress: 2/2" in err


def test_overall_bar_on_a_terminal(capsys) -> None:
    p = Progress(enabled=True)
    bars = [p.add(f"s{k}", total=2) for k in range(3)]
    for bar in bars:
        bar.skip(0)
        for rec in _records(2):
            bar.update(rec)
    p.close()
    err = capsys.readouterr().err
    assert "3 streams" in err and "6/6" in err and "[s0] episode" not in err


def test_quiet_model_loading(monkeypatch) -> None:
    monkeypatch.setenv("HF_HUB_DISABLE_PROGRESS_BARS", "0")   # restored after the test
    monkeypatch.delenv("WORLDMIND_LOADING_BARS", raising=False)
    quiet_model_loading()
    assert os.environ["HF_HUB_DISABLE_PROGRESS_BARS"] == "1"
    if "transformers" in sys.modules:
        from transformers.utils import logging as hf_logging

        assert not hf_logging.is_progress_bar_enabled()
        hf_logging.enable_progress_bar()
