"""`worldmind tasks list|show`."""

from __future__ import annotations

import json

from worldmind_local.cli import main


def test_list_generated(capsys):
    assert main(["tasks", "list", "--benchmark", "eb_alfred", "--suite", "generated", "--per-subset", "2", "--subset", "spatial"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("# eb_alfred generated suite") and len(lines) == 3
    subset, index, task_type, instruction = lines[1].split("\t")
    assert subset == "spatial" and index == "0" and task_type and instruction


def test_show_text_and_json(capsys):
    args = ["tasks", "show", "--benchmark", "eb_alfred", "--suite", "generated", "--subset", "base", "--index", "1"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "expert plan (" in text and "action space:" in text and "initial state: Location:" in text
    assert main(args + ["--actions", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["actions"][:2] == ["find a Cart", "find a Potato"] and record["n_actions"] == len(record["actions"])
    assert all(a in record["actions"] for a in record["expert_plan"])


def test_show_data_pack_episode(eb_data_dir, capsys):
    args = ["tasks", "show", "--benchmark", "eb_alfred", "--data-dir", str(eb_data_dir), "--subset", "base", "--index", "0", "--json"]
    assert main(args) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["instruction"] == "Rinse off a ladle and move it to the table."
    assert record["expert_plan"][-1] == "put down the object in hand"


def test_show_errors(capsys):
    base = ["tasks", "show", "--benchmark", "eb_alfred", "--suite", "generated", "--per-subset", "2"]
    assert main(base + ["--subset", "base", "--index", "5"]) == 2
    assert "out of range" in capsys.readouterr().err
    assert main(base + ["--subset", "nope", "--index", "0"]) == 2
    assert "unknown subset" in capsys.readouterr().err
