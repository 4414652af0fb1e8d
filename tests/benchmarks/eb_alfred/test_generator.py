"""Generated suites: every task's own expert plan succeeds, and a seed always gives the same bytes."""

from __future__ import annotations

import dataclasses
import json
from collections import Counter

from benchmarks.eb_alfred import ADAPTER
from benchmarks.eb_alfred.goals import TASK_TYPES
from benchmarks.eb_alfred.twin import AlfredTwin


def dump(tasks) -> str:
    return json.dumps([dataclasses.asdict(t) for t in tasks], sort_keys=True)


def test_thousand_generated_tasks_succeed_with_their_expert_plans():
    env = AlfredTwin()
    per_subset = 167  # x 6 subsets = 1002 tasks
    types, failures, total = Counter(), [], 0
    for subset in ADAPTER.subsets:
        for task in ADAPTER.generate_tasks(7, subset, per_subset):
            total += 1
            types[task.task_type] += 1
            env.reset(task)
            result = None
            for action in task.expert_plan:
                result = env.step(env.action_id(action))
                if result.done:
                    break
            if not (result and result.success and result.progress == 1.0):
                failures.append(task.id)
    assert total >= 1000 and failures == []
    assert set(types) == set(TASK_TYPES)


def test_same_seed_gives_a_byte_identical_suite():
    for subset in ("base", "spatial", "long_horizon"):
        assert dump(ADAPTER.generate_tasks(3, subset, 12)) == dump(ADAPTER.generate_tasks(3, subset, 12))
        assert dump(ADAPTER.generate_tasks(3, subset, 12)) != dump(ADAPTER.generate_tasks(4, subset, 12))
    # task i depends only on (seed, subset, i)
    assert dump(ADAPTER.generate_tasks(3, "base", 5)) == dump(ADAPTER.generate_tasks(3, "base", 12)[:5])


def test_subset_styles():
    n = 30
    base = ADAPTER.generate_tasks(11, "base", n)
    styled = {s: ADAPTER.generate_tasks(11, s, n) for s in ("common_sense", "visual_appearance", "spatial", "complex_instruction")}
    assert all(t.instruction and t.expert_plan for t in base)
    assert any("something" in t.instruction or "what " in t.instruction or "device" in t.instruction
               for t in styled["common_sense"])
    assert any(" the round " in t.instruction or " the white " in t.instruction for t in styled["visual_appearance"])
    assert sum(" next to the " in t.instruction for t in styled["spatial"]) >= n // 3
    mean_len = {s: sum(len(t.instruction) for t in ts) / n for s, ts in styled.items()}
    assert mean_len["complex_instruction"] > sum(len(t.instruction) for t in base) / n + 20
    long = ADAPTER.generate_tasks(11, "long_horizon", n)
    assert sum(len(t.expert_plan) for t in long) / n > sum(len(t.expert_plan) for t in base) / n


def test_generated_tasks_use_the_record_format():
    task = ADAPTER.generate_tasks(0, "base", 1)[0]
    record, facts = task.payload["record"], task.payload["facts"]
    assert record["task_type"] in TASK_TYPES and record["plan"]["high_pddl"][-1]["planner_action"]["action"] == "NoOp"
    assert set(record["pddl_params"]) == {"object_target", "object_sliced", "parent_target", "mrecep_target", "toggle_target"}
    assert facts["receptacles"] and facts["objects"] and facts["in_receptacle"]
    json.dumps(task.payload)  # JSON-serialisable
