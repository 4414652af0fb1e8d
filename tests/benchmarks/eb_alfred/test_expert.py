"""ALFRED's expert plans (plan.high_pddl of all 213 task records) replay to success on the twin."""

from __future__ import annotations

from benchmarks.eb_alfred.data import load_pack
from benchmarks.eb_alfred.expert import expert_plan
from benchmarks.eb_alfred.scene import build_scene
from benchmarks.eb_alfred.twin import AlfredTwin
from worldmind_local.env import Task


def test_every_task_record_expert_plan_succeeds(eb_data_dir):
    pack = load_pack(eb_data_dir)
    assert len(pack.tasks) == 213
    env = AlfredTwin()
    failures, longest = [], 0
    for key, record in pack.tasks.items():
        facts = pack.trials[key.split("#")[0]]
        plan = expert_plan(build_scene(key, record, facts), record["plan"]["high_pddl"])
        longest = max(longest, len(plan))
        task = Task(id=key, benchmark="eb_alfred", subset="all", index=0, instruction="", task_type=record["task_type"],
                    payload={"key": key, "record": record, "facts": facts})
        env.reset(task)
        result = None
        for action in plan:
            result = env.step(env.action_id(action))
            assert not result.invalid, (key, action, result.feedback)
            if result.done:
                break
        if not (result and result.success and result.progress == 1.0):
            failures.append(key)
    assert failures == []
    assert longest <= 30


def test_adapter_attaches_expert_plans(eb_data_dir):
    from benchmarks.eb_alfred import ADAPTER

    tasks = ADAPTER.load_tasks(eb_data_dir, "long_horizon")
    assert len(tasks) == 50 and all(t.expert_plan for t in tasks)
    assert tasks[0].expert_plan[0].startswith("find a ")
