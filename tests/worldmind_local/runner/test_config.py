from __future__ import annotations

from pathlib import Path

import pytest

from worldmind_local.runner.config import MethodOptions, RunConfig, StreamSpec, expand_streams, load_plan_file


def _streams(**kw):
    base = dict(benchmark="eb_alfred", subsets=["base", "spatial"], methods=["worldmind"], planner="hf:m",
                judge=None, seeds=[0, 1], memory_from=None, memory_budget=None, limit=None,
                options=MethodOptions())
    base.update(kw)
    return expand_streams(**base)


def test_expand_is_product_in_order():
    streams = _streams()
    assert [(s.subset, s.seed) for s in streams] == [("base", 0), ("base", 1), ("spatial", 0), ("spatial", 1)]
    assert len({s.stream_id for s in streams}) == 4


def test_stream_id_distinguishes_options_and_judge():
    a = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m")
    b = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options=MethodOptions(verifier=False))
    c = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", judge="hf:j")
    assert len({a.stream_id, b.stream_id, c.stream_id}) == 3
    assert a.stream_id == "eb_alfred.base.worldmind.m.s0"
    assert a.judge_spec == "hf:m" and c.judge_spec == "hf:j"


def test_duplicate_streams_rejected():
    s = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m")
    with pytest.raises(ValueError, match="duplicate"):
        RunConfig(streams=[s, s])
    with pytest.raises(ValueError):
        RunConfig(streams=[s], wave=0)


def test_plan_file_expands_lists(tmp_path: Path):
    plan = tmp_path / "exp.yaml"
    plan.write_text(
        "defaults: {benchmark: eb_alfred, planner: 'random:seeded-random', limit: 2}\n"
        "run: {suite: generated}\n"
        "streams:\n"
        "  - {subset: base}\n"
        "  - {subsets: [common_sense, spatial], seeds: [0, 1], options: {goal_experience: false}}\n"
    )
    run, streams = load_plan_file(plan)
    assert run == {"suite": "generated"}
    assert len(streams) == 5
    assert all(s.limit == 2 for s in streams)
    assert streams[1].options.goal_experience is False


def test_plan_file_errors_name_the_field(tmp_path: Path):
    plan = tmp_path / "bad.yaml"
    plan.write_text("streams:\n  - {subset: base}\n")  # no benchmark/planner
    with pytest.raises(ValueError, match=r"streams\[0\]"):
        load_plan_file(plan)
    plan.write_text("streams: 3\n")
    with pytest.raises(ValueError, match="streams"):
        load_plan_file(plan)
