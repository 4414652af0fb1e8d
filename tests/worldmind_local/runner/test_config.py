from __future__ import annotations

from pathlib import Path

import pytest

from worldmind_local.runner.config import RunConfig, StreamSpec, expand_streams, load_plan_file


def _streams(**kw):
    base = dict(benchmark="eb_alfred", subsets=["base", "spatial"], methods=["worldmind"], planner="hf:m",
                judge=None, seeds=[0, 1], memory_from=None, memory_budget=None, limit=None,
                options={})
    base.update(kw)
    return expand_streams(**base)


def test_expand_is_product_in_order():
    streams = _streams()
    assert [(s.subset, s.seed) for s in streams] == [("base", 0), ("base", 1), ("spatial", 0), ("spatial", 1)]
    assert len({s.stream_id for s in streams}) == 4


def test_stream_id_distinguishes_options_and_judge():
    a = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m")
    b = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options={"top_k": 3})
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
    # an ablation switch becomes the ablation's method name (one spelling, one stream id)
    assert streams[1].method == "worldmind_process_only" and streams[1].options == {}


def test_plan_file_errors_name_the_field(tmp_path: Path):
    plan = tmp_path / "bad.yaml"
    plan.write_text("streams:\n  - {subset: base}\n")  # no benchmark/planner
    with pytest.raises(ValueError, match=r"streams\[0\]"):
        load_plan_file(plan)
    plan.write_text("streams: 3\n")
    with pytest.raises(ValueError, match="streams"):
        load_plan_file(plan)


def test_ablations_have_one_spelling_whatever_way_they_are_asked():
    by_switch = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options={"goal_experience": False})
    by_name = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", method="worldmind_process_only")
    assert by_switch.method == by_name.method == "worldmind_process_only"
    assert by_switch.stream_id == by_name.stream_id and by_switch.label == by_name.label
    base = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m",
                      options={"goal_experience": False, "process_experience": False, "verifier": False})
    assert base.method == "worldmind_baseline"
    # a default value given explicitly is the same stream as leaving it out
    same = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options={"verify": "first"})
    assert same.options == {} and same.stream_id == "eb_alfred.base.worldmind.m.s0"


def test_options_are_validated_against_the_method_config():
    with pytest.raises(ValueError, match="no option"):
        StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options={"top_kk": 3})
    with pytest.raises(ValueError):
        StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options={"planner_max_tokens": 0})
    with pytest.raises(ValueError, match="no WorldMind variant"):
        StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m",
                   options={"goal_experience": False, "process_experience": False})
    spec = StreamSpec(benchmark="eb_alfred", subset="base", planner="hf:m", options={"top_k": 3})
    assert spec.method_config().top_k == 3 and spec.label == "worldmind[top_k=3]"
