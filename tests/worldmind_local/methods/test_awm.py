"""AWM (online): one workflow text, re-induced from every judged success, injected whole."""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any

from worldmind_local.env import Task
from worldmind_local.memory import ExperienceStore
from worldmind_local.methods.awm import AgentWorkflowMemory
from worldmind_local.methods.base import Method

LEAKS = re.compile(r"progress|task_success|end_reason|max_steps|max_invalid|taxonomy", re.IGNORECASE)
YES = json.dumps({"thoughts": "The apple is in the open fridge.", "status": "success"})
NO = json.dumps({"thoughts": "Nothing confirms the apple was stored.", "status": "failure"})
SOLVE = [(0, "find a Apple"), (1, "pick up the Apple"), (2, "find a Fridge"), (3, "open the Fridge"),
         (4, "put down the object in hand")]


def react_answer(*actions: tuple[int, str], plan: str = "A plan.") -> str:
    return json.dumps({"reasoning_and_reflection": "I reason.", "language_plan": plan,
                       "executable_plan": [{"action_id": i, "action_name": n} for i, n in actions]})


def _other(task: Task, index: int, instruction: str) -> Task:
    return dataclasses.replace(task, id=f"apple-{index}", index=index, instruction=instruction)


def _run(kit: Any, task: Task, store: Any, embedder: Any, planner: list[str], judge: str = YES,
         workflow: str = "Workflow: store {target_object} in {destination_receptacle}", **config: Any) -> tuple[Any, Any]:
    backend = kit.ScriptedBackend({"planner": list(planner)}, defaults={"memory_judge": judge, "inductor": workflow})
    method = AgentWorkflowMemory(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, store, embedder), config=method.config)
    return kit.run_method(method, task, kit.AppleWorld(), ctx), backend


def _text(request: Any) -> str:
    return "\n".join(str(m["content"]) for m in request.messages)


def test_a_judged_success_stores_its_trajectory_and_a_fresh_workflow(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [react_answer(*SOLVE)], workflow="```\nWorkflow: W1\n```")
    assert [e["kind"] for e in rec.experience] == ["trajectory", "workflow"]
    assert rec.experience[1]["text"] == "Workflow: W1"
    assert "Planning call 1\nThink: I reason. A plan.\n  find a Apple -> Last action executed successfully." \
        in rec.experience[0]["text"]
    assert len(backend.of("planner")) == 1 and len(backend.of("memory_judge")) == 1
    (induction,) = backend.of("inductor")
    assert induction.sampling.temperature == 1.0 and induction.sampling.max_tokens == 2048
    prompt = _text(induction)
    assert "Put a key chain on the desk." in prompt   # the embodied one-shot from EB's static examples
    assert prompt.index("# Your turn") < prompt.index("Query: Put the apple in the fridge.")
    assert rec.method_stats["inductions"] == 1 and rec.method_stats["induction_groups"] == 1


def test_a_judged_failure_stores_nothing_and_induces_nothing(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [react_answer(*SOLVE)], judge=NO)
    assert rec.success and rec.experience == [] and not backend.of("inductor")
    assert rec.method_stats["signal_success"] is False and rec.method_stats["success_signal"] == "llm_judge"


def test_the_workflow_is_injected_whole_after_the_examples(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)], workflow="Workflow: carry {target_object}")
    rec, backend = _run(kit, _other(task, 4, "Hold the apple."), store, embedder,
                        [react_answer(*SOLVE[:1]), react_answer(*SOLVE[1:2])], judge=NO)
    assert len(backend.of("planner")) == 3 and not backend.of("inductor")   # 2 plans + the empty default
    for request in backend.of("planner"):
        system, user = (str(m["content"]) for m in request.messages)
        assert system.rindex("## Example ") < system.index("# Workflows induced from past successful tasks")
        assert system.endswith("Workflow: carry {target_object}") and "Workflow: carry" not in user
    assert rec.method_stats["workflow_id"] == store.latest("workflow").id


def test_reinduction_sees_every_success_and_the_newest_text_wins(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)], workflow="W1")
    _run(kit, _other(task, 4, "Hold the apple."), store, embedder, [react_answer(*SOLVE[:2])], judge=NO)
    rec, backend = _run(kit, _other(task, 5, "Cool an apple in the fridge."), store, embedder,
                        [react_answer(*SOLVE)], workflow="W2")
    prompt = _text(backend.of("inductor")[0])
    assert "Query: Put the apple in the fridge." in prompt and "Query: Cool an apple in the fridge." in prompt
    assert "Query: Hold the apple." not in prompt
    assert rec.method_stats["induction_groups"] == 2 and store.latest("workflow").text == "W2"
    assert [e.kind for e in store.entries()] == ["trajectory", "workflow", "trajectory", "workflow"]


def test_oldest_groups_are_dropped_when_the_examples_do_not_fit(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    rec, backend = _run(kit, _other(task, 4, "Cool an apple."), store, embedder, [react_answer(*SOLVE)],
                        induction_max_chars=500)
    prompt = _text(backend.of("inductor")[0])
    assert "Query: Cool an apple." in prompt and "Query: Put the apple in the fridge." not in prompt
    assert rec.method_stats["induction_groups_dropped"] == 1


def test_no_prompt_shows_success_or_progress(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    _, backend = _run(kit, _other(task, 4, "Store an apple in the fridge."), store, embedder, [react_answer(*SOLVE)])
    assert {r.role for r in backend.requests} == {"planner", "memory_judge", "inductor"}
    for request in backend.requests:
        assert not LEAKS.search(_text(request)), request.role


def test_env_signal_and_the_seeded_sampling_repeat(kit, task, embedder) -> None:
    def once() -> Any:
        store = ExperienceStore(embedder)
        _run(kit, task, store, embedder, [react_answer(*SOLVE)], success_signal="env")
        _run(kit, _other(task, 4, "put the apple in the fridge"), store, embedder, [react_answer(*SOLVE[:4])],
             success_signal="env")
        return _run(kit, _other(task, 5, "Put the apple in the fridge"), store, embedder, [react_answer(*SOLVE)],
                    success_signal="env")

    (rec, backend), (_, again) = once(), once()
    assert not backend.of("memory_judge") and rec.method_stats["success_signal"] == "env"
    assert rec.method_stats["induction_groups"] == 1   # one normalised instruction, one sampled trajectory
    assert _text(backend.of("inductor")[0]) == _text(again.of("inductor")[0])
    assert backend.of("inductor")[0].sampling.seed == again.of("inductor")[0].sampling.seed


def test_memory_round_trips_through_load_from_disk(kit, task, embedder, tmp_path) -> None:
    from datasets import load_from_disk

    method = AgentWorkflowMemory()
    store = method.new_memory(embedder, None)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)], workflow="W1")
    store.save(tmp_path / "m")
    assert load_from_disk(str(tmp_path / "m"))["kind"] == ["trajectory", "workflow"]
    assert method.load_memory(str(tmp_path / "m"), embedder, None).latest("workflow").text == "W1"


def test_protocol_and_defaults() -> None:
    cfg = AgentWorkflowMemory().config
    assert isinstance(AgentWorkflowMemory(), Method) and AgentWorkflowMemory.memory_scope == "global"
    assert (cfg.success_signal, cfg.induction_temperature, cfg.induction_max_tokens) == ("llm_judge", 1.0, 2048)
