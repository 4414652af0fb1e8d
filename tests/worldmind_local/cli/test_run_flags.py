"""`worldmind run` refuses bad flags and typos with one line before it creates the run folder, and
says (and records) when a memory from another benchmark is loaded."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from worldmind_local.cli import main

BASE = ["run", "--benchmark", "eb_navigation", "--subsets", "base", "--suite", "generated",
        "--planner", "random:seeded-random", "--progress", "lines"]


@pytest.mark.parametrize("extra, message", [
    (["--limit", "-1"], "expected an integer >= 1"),
    (["--limit", "0"], "expected an integer >= 1"),
    (["--suite-size", "0"], "expected an integer >= 1"),
    (["--max-concurrency", "0"], "expected an integer >= 1"),
    (["--memory-budget", "-3"], "expected an integer >= 0"),
    (["--planner-max-tokens", "0"], "planner_max_tokens"),
    (["--top-k", "-1"], "top_k"),
    (["--planner", "random:seeded-randomm"], "did you mean random:seeded-random"),
    (["--judge", "hf:smollm2-135m-instruc"], "unknown model spec"),
    (["--method", "worldmind,reactt"], "unknown method"),
    (["--subsets", "bse"], "unknown subset"),
])
def test_bad_flags_fail_in_one_line_and_create_nothing(tmp_path: Path, capsys, extra, message) -> None:
    out = tmp_path / "run"
    with pytest.raises(SystemExit) if extra[0] in ("--limit", "--suite-size", "--max-concurrency",
                                                    "--memory-budget") else _no_raise():
        rc = main([*BASE, "--out", str(out), *extra])
        assert rc == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()


def test_out_naming_a_file_is_refused(tmp_path: Path, capsys) -> None:
    target = tmp_path / "a-file"
    target.write_text("x")
    assert main([*BASE, "--limit", "1", "--out", str(target)]) == 2
    err = capsys.readouterr().err
    assert "a-file" in err and "Traceback" not in err and target.read_text() == "x"


def test_a_corrected_command_runs_after_a_typo(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    assert main([*BASE, "--limit", "1", "--out", str(out), "--planner", "random:nope"]) == 2
    assert main([*BASE, "--limit", "1", "--out", str(out)]) == 0


def test_cross_environment_memory_is_said_and_recorded(tmp_path: Path, capsys) -> None:
    nav = tmp_path / "nav"
    assert main([*BASE, "--limit", "2", "--out", str(nav)]) == 0
    [memory] = list((nav / "streams").glob("*/memory"))
    alfred = tmp_path / "alfred"
    capsys.readouterr()
    assert main(["run", "--benchmark", "eb_alfred", "--subsets", "base", "--suite", "generated", "--limit", "1",
                 "--planner", "random:seeded-random", "--progress", "lines", "--out", str(alfred),
                 "--memory-from", str(memory)]) == 0
    err = capsys.readouterr().err
    assert "cross-environment" in err and "eb_navigation" in err
    facts = next(iter(json.loads((alfred / "manifest.json").read_text())["memory_sources"].values()))
    assert facts["cross_environment"] is True and facts["benchmarks"] == ["eb_navigation"]
    results = json.loads((alfred / "results.json").read_text())
    assert next(iter(results["memory_sources"].values()))["cross_environment"] is True


class _no_raise:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> bool:
        return False
