"""Preflight checks (issue 18): a mistyped command fails in one line before the run folder exists."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from worldmind_local.runner.preflight import check_memory_source, check_model_specs, check_out_path


def test_out_path(tmp_path: Path) -> None:
    assert check_out_path(tmp_path / "new" / "run") == tmp_path / "new" / "run"
    assert check_out_path(tmp_path) == tmp_path
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="is an existing file") as err:
        check_out_path(tmp_path / "file")
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match="cannot be created under it"):
        check_out_path(tmp_path / "file" / "run")
    assert not (tmp_path / "new").exists()  # nothing was created


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_out_path_not_writable(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    with pytest.raises(ValueError, match="not writable"):
        check_out_path(locked / "run")


def test_model_specs_resolve_without_weights() -> None:
    specs = check_model_specs(["random:seeded-random", "hf:tiny-qwen3", "replay", "replay:org/model",
                               "replay:hf:tiny-qwen3", "random:seeded-random"])
    assert specs["hf:tiny-qwen3"].model_id == "worldmind-local/tiny-qwen3-random"
    assert specs["replay"] is None and specs["replay:org/model"] is None
    assert specs["replay:hf:tiny-qwen3"].name == "tiny-qwen3"


@pytest.mark.parametrize(("typo", "suggestion"), [("hf:tiny-qwen", "hf:tiny-qwen3"),
                                                  ("hf:smolm2-135m-instruct", "hf:smollm2-135m-instruct"),
                                                  ("tiny-qwen3", "hf:tiny-qwen3"),
                                                  ("random:seeded-randon", "random:seeded-random"),
                                                  ("replay:hf:tiny-qwen4", "hf:tiny-qwen3")])
def test_a_typo_lists_close_matches_in_one_line(typo: str, suggestion: str) -> None:
    with pytest.raises(ValueError, match="did you mean") as err:
        check_model_specs(["random:seeded-random", typo])
    assert suggestion in str(err.value) and "\n" not in str(err.value)


def test_no_close_match_still_one_line() -> None:
    with pytest.raises(ValueError, match="unknown model spec 'hf:zzzz' \\(`worldmind models list`"):
        check_model_specs(["hf:zzzz"])


def test_memory_source(tmp_path: Path) -> None:
    memory = tmp_path / "run" / "streams" / "s1" / "memory"
    memory.mkdir(parents=True)
    (memory / "dataset_info.json").write_text("{}")
    assert check_memory_source(memory) == memory
    with pytest.raises(ValueError, match="is a run folder.*streams/s1/memory"):
        check_memory_source(tmp_path / "run")
    with pytest.raises(FileNotFoundError, match="no such folder"):
        check_memory_source(tmp_path / "absent")
    (tmp_path / "file.parquet").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        check_memory_source(tmp_path / "file.parquet")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="does not look like a repository"):
        check_memory_source(tmp_path / "empty")
