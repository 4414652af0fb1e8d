"""`--task-order-seed`: a permutation, the same one per seed, applied to a stream's task list."""

from __future__ import annotations

import pytest

from worldmind_local.perturb import permute, task_order
from worldmind_local.runner.config import RunConfig, StreamSpec


@pytest.mark.parametrize("n", [1, 2, 7, 50])
def test_task_order_is_a_permutation_and_the_same_per_seed(n: int) -> None:
    for seed in range(5):
        order = task_order(n, seed)
        assert sorted(order) == list(range(n))
        assert order == task_order(n, seed)
    if n >= 7:
        assert len({tuple(task_order(n, s)) for s in range(5)}) > 1


def test_permute_keeps_items_and_none_is_identity() -> None:
    items = list("abcdefgh")
    assert permute(items, None) == items
    assert sorted(permute(items, 3)) == items and permute(items, 3) == permute(items, 3)


def test_stream_identity_and_the_runners_task_list() -> None:
    from worldmind_local.runner.run import _suite_tasks

    plain = StreamSpec(benchmark="eb_alfred", subset="base", planner="random:seeded-random", limit=6)
    shuffled = plain.model_copy(update={"task_order_seed": 2})
    shuffled = StreamSpec(**shuffled.model_dump())
    assert plain.stream_id != shuffled.stream_id
    assert StreamSpec(**shuffled.model_dump()).stream_id == shuffled.stream_id
    config = RunConfig(streams=[plain, shuffled], suite="generated", suite_size=6)
    base, _ = _suite_tasks(config, plain)
    moved, _ = _suite_tasks(config, shuffled)
    assert [t.index for t in moved] == [base[i].index for i in task_order(6, 2)]
    assert sorted(t.index for t in moved) == [t.index for t in base]   # the same episodes


def test_unset_stress_tests_leave_ids_and_identity_as_before() -> None:
    spec = StreamSpec(benchmark="eb_alfred", subset="base", planner="random:seeded-random", memory_budget=10)
    import hashlib
    import json

    old_hash = hashlib.sha256(json.dumps({"memory_budget": 10, "memory_from": None, "options": {}},
                                         sort_keys=True).encode()).hexdigest()[:8]
    assert spec.stream_id == f"eb_alfred.base.worldmind.seeded-random.s0.{old_hash}"
    identity = RunConfig(streams=[spec]).identity()
    assert "perturb" not in identity["streams"][0] and "task_order_seed" not in identity["streams"][0]


def test_run_flags_make_one_stream_per_task_order_seed_with_the_perturbation() -> None:
    from worldmind_local.cli import build_parser
    from worldmind_local.cli.run import build_config

    args = build_parser().parse_args(["run", "--benchmark", "eb_alfred", "--subsets", "base", "--planner",
                                      "random:seeded-random", "--perturb", "rename", "--task-order-seed", "0,3"])
    config, _ = build_config(args)
    assert [(s.perturb, s.task_order_seed) for s in config.streams] == [("rename", 0), ("rename", 3)]
    bad = build_parser().parse_args(["run", "--planner", "random:seeded-random", "--perturb", "poison:0"])
    with pytest.raises(ValueError, match="RATE"):
        build_config(bad)
