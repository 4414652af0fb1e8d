"""Synapse: successful trajectories as exemplars in ReAct's examples slot, retrieved by task specifier."""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any

from worldmind_local.env import Task
from worldmind_local.memory import ExperienceStore
from worldmind_local.methods.base import Method
from worldmind_local.methods.react import ReAct
from worldmind_local.methods.synapse import Synapse, specifier

LEAKS = re.compile(r"progress|task_success|end_reason|max_steps|max_invalid|taxonomy", re.IGNORECASE)
YES = json.dumps({"thoughts": "The apple is in the open fridge.", "status": "success"})
NO = json.dumps({"thoughts": "Nothing confirms the apple was stored.", "status": "failure"})


def react_answer(*actions: tuple[int, str], reasoning: str = "I reason.", plan: str = "A plan.") -> str:
    return json.dumps({"reasoning_and_reflection": reasoning, "language_plan": plan,
                       "executable_plan": [{"action_id": i, "action_name": n} for i, n in actions]})


SOLVE = [(i, n) for i, n, _ in (
    (0, "find a Apple", ""), (1, "pick up the Apple", ""), (2, "find a Fridge", ""), (3, "open the Fridge", ""),
    (4, "put down the object in hand", ""))]


def _other(task: Task, index: int, instruction: str) -> Task:
    return dataclasses.replace(task, id=f"apple-{index}", index=index, instruction=instruction)


def _run(kit: Any, task: Task, store: Any, embedder: Any, planner: list[str], judge: str = YES,
         method: Any = None, **config: Any) -> tuple[Any, Any]:
    backend = kit.ScriptedBackend({"planner": list(planner)}, defaults={"memory_judge": judge})
    method = method or Synapse(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, store, embedder), config=method.config)
    return kit.run_method(method, task, kit.AppleWorld(), ctx), backend


def _text(request: Any) -> str:
    return "\n".join(str(m["content"]) for m in request.messages)


def test_a_judged_success_stores_one_exemplar_keyed_by_specifier(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [react_answer(*SOLVE[:2], plan="Get the apple."),
                                                     react_answer(*SOLVE[2:], plan="Store it.")])
    assert rec.success and len(backend.of("planner")) == rec.planner_calls == 2
    assert len(backend.of("memory_judge")) == 1 and {r.role for r in backend.requests} == {"planner", "memory_judge"}
    (item,) = rec.experience
    assert item["kind"] == "exemplar" and item["key"] == specifier("eb_alfred", "base", task.instruction)
    assert item["success_signal"] == "llm_judge" and item["judge_model"] == "scripted/planner"
    text = item["text"]
    assert text.startswith("Task: Put the apple in the fridge.")
    assert text.count("Observation:") == 2 and "start of the episode" in text
    assert "last feedback: Last action executed successfully." in text
    assert '"executable_plan": [{"action_name": "find a Fridge"}' in text and "action_id" not in text
    assert "  open the Fridge -> Last action executed successfully." in text
    assert rec.method_stats["signal_success"] is True and rec.method_stats["judge_calls"] == 1


def test_the_signal_not_the_env_decides(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, _ = _run(kit, task, store, embedder, [react_answer(*SOLVE)], judge=NO)
    assert rec.success and rec.experience == [] and rec.method_stats["signal_success"] is False
    failed, _ = _run(kit, _other(task, 4, "Hold the apple."), store, embedder, [react_answer(*SOLVE[:1])], judge=YES)
    assert not failed.success and [e["kind"] for e in failed.experience] == ["exemplar"]
    env_rec, backend = _run(kit, _other(task, 5, "Cool an apple."), store, embedder, [react_answer(*SOLVE)],
                            judge=NO, success_signal="env")
    assert not backend.of("memory_judge") and len(env_rec.experience) == 1
    assert env_rec.method_stats["success_signal"] == "env"


def test_the_next_episode_shows_it_after_the_static_examples(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    first, _ = _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    rec, backend = _run(kit, _other(task, 4, "Store an apple in the fridge."), store, embedder,
                        [react_answer(*SOLVE[:1]), react_answer(*SOLVE[1:])])
    assert rec.retrieved_ids == [first.experience[0]["id"]]
    for request in backend.of("planner"):
        system, user = (str(m["content"]) for m in request.messages)
        static = system.rindex("## Example ")
        retrieved = system.index("## Retrieved successful trajectory 1")
        assert static < retrieved < system.index("# Output")
        assert first.experience[0]["text"] in system and "Retrieved successful" not in user
    assert len(backend.of("planner")) == 2 and len(backend.of("memory_judge")) == 1


def test_an_empty_memory_is_plain_react(kit, task, embedder) -> None:
    _, synapse = _run(kit, task, ExperienceStore(embedder), embedder, [react_answer(*SOLVE)])
    _, react = _run(kit, task, None, embedder, [react_answer(*SOLVE)], method=ReAct())
    assert synapse.of("planner")[0].messages == react.of("planner")[0].messages


def test_top_three_and_self_exclusion(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    for i, words in enumerate(("Chill the apple.", "Fridge an apple.", "Apple to fridge.", "Cold apple.")):
        _run(kit, _other(task, 10 + i, words), store, embedder, [react_answer(*SOLVE, plan=f"plan {i}")])
    _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    rec, _ = _run(kit, _other(task, 30, "put the apple in the fridge"), store, embedder, [react_answer(*SOLVE)])
    shown = [e.instruction for e in store.entries() if e.id in rec.retrieved_ids]
    assert len(shown) == 3 and "Put the apple in the fridge." not in shown
    assert rec.method_stats["exemplars_shown"] == 3


def test_exemplars_are_added_only_while_they_fit(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    backend = kit.ScriptedBackend({"planner": [react_answer(*SOLVE)]}, defaults={"memory_judge": YES})
    backend.spec.context_length = 2048 + 10   # room for the prompt? no: nothing fits beside the output budget
    method = Synapse()
    ctx = dataclasses.replace(kit.make_ctx(backend, store, embedder), config=method.config)
    rec = kit.run_method(method, _other(task, 4, "Store an apple in the fridge."), kit.AppleWorld(), ctx)
    assert rec.retrieved_ids == [] and rec.method_stats["exemplars_over_budget"] == 1


def test_no_prompt_shows_success_or_progress(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    _, backend = _run(kit, _other(task, 4, "Store an apple in the fridge."), store, embedder, [react_answer(*SOLVE)])
    assert {r.role for r in backend.requests} == {"planner", "memory_judge"}
    for request in backend.requests:
        assert not LEAKS.search(_text(request)), request.role
    judge = _text(backend.of("memory_judge")[0])
    assert "Store an apple in the fridge." in judge and "I reason. A plan." in judge
    assert backend.of("memory_judge")[0].sampling.temperature == 0.0


def test_memory_round_trips_through_load_from_disk(kit, task, embedder, tmp_path) -> None:
    from datasets import load_from_disk

    method = Synapse()
    store = method.new_memory(embedder, None)
    rec, _ = _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    store.save(tmp_path / "m")
    rows = load_from_disk(str(tmp_path / "m"))
    assert rows["key"] == [specifier("eb_alfred", "base", task.instruction)] and rows["kind"] == ["exemplar"]
    loaded = method.load_memory(str(tmp_path / "m"), embedder, None)
    assert [e.id for e in loaded.entries()] == [rec.experience[0]["id"]]


def test_protocol_and_defaults() -> None:
    assert isinstance(Synapse(), Method) and Synapse.memory_scope == "global"
    assert Synapse().config.success_signal == "llm_judge" and Synapse().config.top_k is None
