"""ReasoningBank: <=3 reasoning items per episode from successes and failures; the top-1 past task's items."""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any

from worldmind_local.env import Task
from worldmind_local.memory import ExperienceStore
from worldmind_local.methods.base import Method
from worldmind_local.methods.reasoningbank import ReasoningBank, parse_items

LEAKS = re.compile(r"progress|task_success|end_reason|max_steps|max_invalid|taxonomy", re.IGNORECASE)
YES = json.dumps({"thoughts": "The apple is in the open fridge.", "status": "success"})
NO = json.dumps({"thoughts": "The apple never reached the fridge.", "status": "failure"})
SOLVE = [(0, "find a Apple"), (1, "pick up the Apple"), (2, "find a Fridge"), (3, "open the Fridge"),
         (4, "put down the object in hand")]


def items(*titles: str) -> str:
    return json.dumps({"reasoning": "why", "memory_items": [
        {"title": t, "description": f"when {t}", "content": f"insight {t}"} for t in titles]})


def react_answer(*actions: tuple[int, str]) -> str:
    return json.dumps({"reasoning_and_reflection": "I reason.", "language_plan": "A plan.",
                       "executable_plan": [{"action_id": i, "action_name": n} for i, n in actions]})


def _other(task: Task, index: int, instruction: str) -> Task:
    return dataclasses.replace(task, id=f"apple-{index}", index=index, instruction=instruction)


def _run(kit: Any, task: Task, store: Any, embedder: Any, planner: list[str], judge: str = YES,
         extracted: str | None = None, **config: Any) -> tuple[Any, Any]:
    backend = kit.ScriptedBackend({"planner": list(planner)},
                                  defaults={"memory_judge": judge, "extractor": extracted or items("A", "B")})
    method = ReasoningBank(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, store, embedder), config=method.config)
    return kit.run_method(method, task, kit.AppleWorld(), ctx), backend


def _text(request: Any) -> str:
    return "\n".join(str(m["content"]) for m in request.messages)


def test_a_success_is_judged_then_distilled_into_items(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [react_answer(*SOLVE)], extracted=items("A", "B", "C", "D"))
    assert [e["title"] for e in rec.experience] == ["A", "B", "C"]   # at most 3
    assert all(e["kind"] == "memory_item" and e["success"] is True for e in rec.experience)
    assert rec.experience[0]["description"] == "when A" and rec.experience[0]["text"] == "insight A"
    assert len(backend.of("planner")) == 1 and len(backend.of("memory_judge")) == 1
    (extraction,) = backend.of("extractor")
    prompt = _text(extraction)
    assert extraction.sampling.temperature == 1.0 and "Work out why it succeeded" in prompt
    assert "**Query:** Put the apple in the fridge." in prompt
    assert "The task succeeded because: The apple is in the open fridge." in prompt
    assert rec.method_stats["items_extracted"] == 3 and rec.method_stats["stored"] == 3


def test_a_failure_is_distilled_with_the_failure_prompt(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    rec, backend = _run(kit, task, store, embedder, [react_answer(*SOLVE[:1])], judge=NO, extracted=items("L"))
    assert not rec.success and [e["success"] for e in rec.experience] == [False]
    prompt = _text(backend.of("extractor")[0])
    assert "Work out why it failed" in prompt and "The task failed because: The apple never reached" in prompt
    env_rec, env_backend = _run(kit, _other(task, 4, "Hold it."), store, embedder, [react_answer(*SOLVE[:1])],
                                success_signal="env")
    assert not env_backend.of("memory_judge") and "The task failed." in _text(env_backend.of("extractor")[0])
    assert env_rec.method_stats["success_signal"] == "env" and env_rec.method_stats["signal_success"] is False


def test_the_next_episode_gets_all_items_of_the_top_past_task(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    first, _ = _run(kit, task, store, embedder, [react_answer(*SOLVE)], extracted=items("A", "B"))
    rec, backend = _run(kit, _other(task, 4, "Store an apple in the fridge."), store, embedder,
                        [react_answer(*SOLVE[:1]), react_answer(*SOLVE[1:])])
    assert rec.retrieved_ids == [e["id"] for e in first.experience]
    for request in backend.of("planner"):
        system, user = (str(m["content"]) for m in request.messages)
        block = system.index("# Memory items from past interactions")
        assert system.rindex("## Example ") < block
        assert system.index("# Memory Item 1\n## Title A") > block and "## Content insight B" in system
        assert "Memory Item" not in user
    assert len(backend.of("planner")) == 2 and len(backend.of("extractor")) == 1


def test_top_one_task_only_and_self_exclusion(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)], extracted=items("self"))
    _run(kit, _other(task, 4, "Chill the apple."), store, embedder, [react_answer(*SOLVE)], extracted=items("X", "Y"))
    _run(kit, _other(task, 5, "Cool the apple."), store, embedder, [react_answer(*SOLVE)], extracted=items("Z"))
    rec, _ = _run(kit, _other(task, 6, "put the apple in the fridge"), store, embedder, [react_answer(*SOLVE)])
    titles = [e.title for e in store.entries() if e.id in rec.retrieved_ids]
    assert titles in (["X", "Y"], ["Z"])   # one past task, all its items, never the identical instruction


def test_parse_items_reads_markdown_headers_when_not_json() -> None:
    text = ("Some reasoning.\n# Memory Item 1\n## Title Open first\n## Description When storing.\n"
            "## Content Open a closed receptacle before putting.\n\n# Memory Item 2\n## Title Empty\n## Content \n")
    assert parse_items(text) == [("Open first", "When storing.", "Open a closed receptacle before putting.")]
    assert parse_items("no items here") == []


def test_no_prompt_shows_success_or_progress(kit, task, embedder) -> None:
    store = ExperienceStore(embedder)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)])
    _, backend = _run(kit, _other(task, 4, "Store an apple in the fridge."), store, embedder, [react_answer(*SOLVE)])
    assert {r.role for r in backend.requests} == {"planner", "memory_judge", "extractor"}
    for request in backend.requests:
        assert not LEAKS.search(_text(request)), request.role


def test_memory_round_trips_through_load_from_disk(kit, task, embedder, tmp_path) -> None:
    from datasets import load_from_disk

    method = ReasoningBank()
    store = method.new_memory(embedder, None)
    _run(kit, task, store, embedder, [react_answer(*SOLVE)], extracted=items("A", "B"))
    store.save(tmp_path / "m")
    rows = load_from_disk(str(tmp_path / "m"))
    assert rows["title"] == ["A", "B"] and rows["description"] == ["when A", "when B"]
    loaded = method.load_memory(str(tmp_path / "m"), embedder, None)
    assert [e.title for e in loaded.entries("memory_item")] == ["A", "B"]


def test_protocol_and_defaults() -> None:
    cfg = ReasoningBank().config
    assert isinstance(ReasoningBank(), Method) and ReasoningBank.memory_scope == "global"
    assert (cfg.success_signal, cfg.extraction_temperature) == ("llm_judge", 1.0)
