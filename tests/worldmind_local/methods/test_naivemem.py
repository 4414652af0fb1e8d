"""NaiveMem: raw successful trajectories in WorldMind's prompt, WorldMind's top-k instruction retriever."""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any

from worldmind_local.env import Task
from worldmind_local.memory import ExperienceStore
from worldmind_local.methods.base import Method
from worldmind_local.methods.naivemem import NaiveMem

LEAKS = re.compile(r"progress|task_success|end_reason|max_steps|max_invalid|taxonomy", re.IGNORECASE)
JUDGE = {"memory_judge": json.dumps({"thoughts": "The apple ended in the fridge.", "status": "success"})}


def _other(task: Task, index: int, instruction: str) -> Task:
    return dataclasses.replace(task, id=f"apple-{index}", index=index, instruction=instruction)


def _run(kit: Any, task: Task, store: Any, embedder: Any, planner: list[str], **config: Any) -> tuple[Any, Any]:
    backend = kit.ScriptedBackend({"planner": list(planner)}, defaults=JUDGE)
    method = NaiveMem(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, store, embedder), config=method.config)
    return kit.run_method(method, task, kit.AppleWorld(), ctx), backend


def _text(request: Any) -> str:
    return "\n".join(str(m["content"]) for m in request.messages)


def test_a_success_stores_the_raw_trajectory_without_a_call(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [kit.plan_json(*kit.SOLVE)])
    assert rec.success and {r.role for r in backend.requests} == {"planner"}
    assert len(backend.of("planner")) == rec.planner_calls == 1
    (item,) = rec.experience
    assert item["kind"] == "trajectory" and item["success"] is True and item["success_signal"] == "env"
    assert "key_embedding" not in item and item["kept"] is True
    # WorldMind's distiller input: every step with its feedback and the (past) task progress marked
    assert "Step 4: action id 4, put down the object in hand" in item["text"] and "task_progress: 1.00" in item["text"]
    assert rec.method_stats["success_signal"] == "env" and rec.method_stats["signal_success"] is True
    assert rec.method_stats["stored"] == 1


def test_a_failure_stores_nothing(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [kit.plan_json((0, "find a Apple", "next to it"))])
    assert not rec.success and rec.end_reason == "empty_plan" and rec.experience == [] and len(store) == 0
    assert rec.method_stats["signal_success"] is False and len(backend.requests) == rec.planner_calls == 2


def test_the_next_episode_sees_it_where_worldmind_puts_goal_experience(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    first, _ = _run(kit, task, store, embedder, [kit.plan_json(*kit.SOLVE)])
    second_task = _other(task, 4, "Store an apple in the fridge.")
    rec, backend = _run(kit, second_task, store, embedder,
                        [kit.plan_json((0, "find a Apple", "x")), kit.plan_json(*kit.SOLVE[1:])])
    assert len(backend.of("planner")) == 2
    for request in backend.of("planner"):   # retrieved on every planner call, in the user message
        system, user = (str(m["content"]) for m in request.messages)
        assert "Successful trajectories from similar past tasks" not in system
        header = user.index("## Human instruction")
        block = user.index("## Knowledge from your World Knowledge Repository")
        history = user.index("## What you have done so far in this episode")
        assert header < block < history
        assert "Original Task: Put the apple in the fridge." in user[block:history]
        assert first.experience[0]["text"] in user[block:history]
        assert '"predicted_state"' in system   # WorldMind's output schema, not ReAct's
    assert rec.retrieved_ids == [first.experience[0]["id"]]
    assert len(store) == 2


def test_same_instruction_is_never_retrieved(kit, task, embedder) -> None:
    store = NaiveMem().new_memory(embedder, None)   # exact-text dedup (§8)
    _run(kit, task, store, embedder, [kit.plan_json(*kit.SOLVE)])
    again = _other(task, 9, "put the apple in the fridge")
    rec, backend = _run(kit, again, store, embedder, [kit.plan_json(*kit.SOLVE)])
    assert rec.retrieved_ids == [] and "World Knowledge Repository" not in _text(backend.of("planner")[0])
    assert rec.experience[0]["kept"] is False and store.rejected_duplicates == 1 and len(store) == 1  # same text


def test_top_k_follows_worldmind(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    for i, words in enumerate(("Put an apple into the fridge.", "Fridge the apple.", "Chill the apple.")):
        _run(kit, _other(task, 10 + i, words), store, embedder,
             [kit.plan_json((0, "find a Apple", "x"), language_plan=f"plan {i}"), kit.plan_json(*kit.SOLVE[1:])])
    rec, _ = _run(kit, task, store, embedder, [kit.plan_json(*kit.SOLVE)])
    assert len(rec.retrieved_ids) == 2   # EB-ALFRED's WorldMind k
    rec, _ = _run(kit, _other(task, 20, "x"), store, embedder, [kit.plan_json(*kit.SOLVE)], top_k=1)
    assert len(rec.retrieved_ids) == 1


def test_no_prompt_shows_success_or_progress(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _, backend = _run(kit, task, store, embedder, [kit.plan_json(*kit.SOLVE)], success_signal="llm_judge")
    assert len(backend.of("memory_judge")) == 1
    for request in backend.requests:
        assert not LEAKS.search(_text(request)), request.role
    # the progress-free format keeps every later prompt clean as well
    c6 = ExperienceStore(embedder)
    _run(kit, task, c6, embedder, [kit.plan_json(*kit.SOLVE)], trajectory_format="c6")
    _, backend = _run(kit, _other(task, 5, "Store an apple in the fridge."), c6, embedder,
                      [kit.plan_json(*kit.SOLVE)], trajectory_format="c6")
    assert all(not LEAKS.search(_text(r)) for r in backend.requests)
    assert "put down the object in hand -> Last action executed successfully." in _text(backend.of("planner")[0])


def test_llm_judge_signal_decides_the_write(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]}, defaults={
        "memory_judge": json.dumps({"thoughts": "not sure the door closed", "status": "failure"})})
    method = NaiveMem({"success_signal": "llm_judge"})
    ctx = dataclasses.replace(kit.make_ctx(backend, store, embedder), config=method.config)
    rec = kit.run_method(method, task, kit.AppleWorld(), ctx)
    assert rec.success and rec.experience == []
    assert rec.method_stats["success_signal"] == "llm_judge" and rec.method_stats["signal_success"] is False
    (judge,) = backend.of("memory_judge")
    assert judge.sampling.temperature == 0.0 and "Put the apple in the fridge." in _text(judge)


def test_memory_round_trips_through_load_from_disk(kit, task, embedder, tmp_path) -> None:
    from datasets import load_from_disk

    method = NaiveMem()
    store = method.new_memory(embedder, None)
    rec, _ = _run(kit, task, store, embedder, [kit.plan_json(*kit.SOLVE)])
    store.commit(task.index)
    store.save(tmp_path / "memory")
    rows = load_from_disk(str(tmp_path / "memory"))
    assert rows["id"] == [rec.experience[0]["id"]] and rows["kind"] == ["trajectory"]
    loaded = method.load_memory(str(tmp_path / "memory"), embedder, None)
    assert isinstance(loaded, ExperienceStore) and loaded.commits == [] and loaded.dedup == "text"
    assert [e.id for e in loaded.entries()] == [e.id for e in store.entries()]


def test_protocol_and_scope() -> None:
    assert isinstance(NaiveMem(), Method) and NaiveMem.memory_scope == "global"
    assert NaiveMem().config.success_signal == "env"


def test_without_memory_it_is_the_worldmind_baseline(kit, task) -> None:
    rec, backend = _run(kit, task, None, None, [kit.plan_json(*kit.SOLVE)])
    assert rec.success and rec.experience == [] and {r.role for r in backend.requests} == {"planner"}
