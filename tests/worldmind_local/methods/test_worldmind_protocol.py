"""WorldMind's protocol point by point (paper first, the official code where the paper is silent):
what the judge is shown, when experience is retrieved, the few-shot examples, the memory budget's unit."""

from __future__ import annotations

import asyncio
import dataclasses
import json
from typing import Any

from worldmind_local.env import ExampleAction, WorkedExample
from worldmind_local.memory import ExperienceEntry, WorldKnowledgeRepository
from worldmind_local.methods.worldmind import WorldMind


def _text(request: Any) -> str:
    return "\n".join(m["content"] if isinstance(m["content"], str) else m["content"][-1]["text"]
                     for m in request.messages)


def _run(kit: Any, task: Any, backend: Any, memory: Any = None, embedder: Any = None, adapter: Any = None,
         **config: Any) -> Any:
    method = WorldMind(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, memory, embedder), config=method.config, adapter=adapter)
    return kit.run_method(method, task, kit.AppleWorld(), ctx)


def _wrong_then_solve(kit: Any) -> Any:
    return kit.ScriptedBackend({
        "planner": [kit.plan_json((1, "pick up the Apple", "I am holding the Apple.")), kit.plan_json(*kit.SOLVE)],
        "judge": [kit.verdict_json(False, "hand is empty")],
        "reflector": [json.dumps({"rules": ["Find an object before picking it up."]})],
    })


def test_the_judge_sees_the_prediction_and_the_actual_state_only(kit, task, memory, embedder) -> None:
    backend = _wrong_then_solve(kit)
    _run(kit, task, backend, memory, embedder)
    judged = _text(backend.of("judge")[0])
    assert "I am holding the Apple." in judged and "You are at the start." in judged
    assert "Cannot find Apple" not in judged and "feedback" not in judged.lower()
    assert "pick up the Apple" not in judged  # not even the action (official discriminator)


def test_judge_feedback_is_an_option(kit, task, memory, embedder) -> None:
    backend = _wrong_then_solve(kit)
    _run(kit, task, backend, memory, embedder, judge_feedback=True)
    judged = _text(backend.of("judge")[0])
    assert "Environment feedback for the action: Last action is invalid. Cannot find Apple" in judged
    assert "Feedback saying the action was invalid" in judged


def test_process_experience_is_retrieved_once_per_episode(kit, task, embedder) -> None:
    memory = WorldKnowledgeRepository(embedder)
    rule = ExperienceEntry(partition="process", text="Open the fridge before putting things in.",
                           instruction="Put the apple in the fridge.", benchmark="eb_alfred", subset="base",
                           episode=0, task_id="old")
    asyncio.run(memory.add([rule]))
    calls: list[str] = []
    original = memory.retrieve
    memory.retrieve = lambda q, p, k, **kw: calls.append(p) or original(q, p, k, **kw)  # type: ignore[method-assign]
    backend = _wrong_then_solve(kit)
    rec = _run(kit, task, backend, memory, embedder)
    assert calls.count("process") == 1 and calls.count("goal") == 2  # goal: every planner call
    assert all("Open the fridge before putting things in." in _text(r) for r in backend.of("planner"))
    assert [p.extra["retrieved_process"] for p in rec.plans] == [[rule.id], [rule.id]]


class _Adapter:
    """A benchmark adapter stand-in that records what worked examples were asked for."""

    default_top_k, default_n_shots, unusable_output, text_stand_in_for_image = 2, 2, "invalid", False

    def __init__(self) -> None:
        self.asked: list[tuple[int, tuple[str, ...]]] = []

    def worked_examples(self, n: int, *, data_dir: Any = None, exclude: Any = ()) -> list[WorkedExample]:
        self.asked.append((n, tuple(exclude)))
        pool = [WorkedExample(f"ex-{i}", f"Example task {i}.", "why", f"plan {i}",
                              (ExampleAction(3, "open the Fridge", f"The fridge is open ({i}).",
                                             "Last action executed successfully."),)) for i in range(5)]
        return [e for e in pool if e.task_id not in exclude and e.instruction not in exclude][:n]


def test_examples_are_in_the_prompt_and_never_from_the_evaluated_task(kit, task) -> None:
    adapter = _Adapter()
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    rec = _run(kit, task, backend, adapter=adapter)
    assert adapter.asked == [(2, (task.id, task.instruction))]
    system = backend.of("planner")[0].messages[0]["content"]
    assert "Human instruction: Example task 0." in system and "Human instruction: Example task 1." in system
    assert '"predicted_state": "The fridge is open (0)."' in system and "Example task 2." not in system
    assert rec.method_stats["examples"] == 2
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    _run(kit, task, backend, adapter=_Adapter(), n_shots=0)
    assert "Example task" not in backend.of("planner")[0].messages[0]["content"]


def test_top_k_defaults_to_the_benchmarks_value() -> None:
    from worldmind_local.registry import BENCHMARKS

    # the official configs eb-alf.yaml, eb-hab.yaml, eb-nav.yaml
    assert [BENCHMARKS.get(b).default_top_k for b in ("eb_alfred", "eb_habitat", "eb_navigation")] == [2, 1, 2]
    assert [BENCHMARKS.get(b).default_n_shots for b in ("eb_alfred", "eb_habitat", "eb_navigation")] == [10, 10, 3]


def _entry(episode: int, text: str) -> ExperienceEntry:
    return ExperienceEntry(partition="process", text=text, instruction=f"task {episode}", benchmark="eb_alfred",
                           subset="base", episode=episode, task_id=f"t{episode}")


def test_memory_budget_counts_experiences_of_episodes_by_default(embedder) -> None:
    """MemN: at most N experiences, an experience being what one episode contributes (paper); each
    reflection's rules and the workflow of an admitted episode enter together."""
    repo = WorldKnowledgeRepository(embedder, budget=2)
    kept = asyncio.run(repo.add([_entry(0, "rule a"), _entry(0, "rule b"), _entry(0, "rule c"),
                                 _entry(1, "rule d"), _entry(2, "rule e"), _entry(1, "rule f")]))
    assert kept == [True, True, True, True, False, True] and repo.rejected_budget == 1
    per_entry = WorldKnowledgeRepository(embedder, budget=2, budget_unit="entries")
    assert asyncio.run(per_entry.add([_entry(0, "rule a"), _entry(0, "rule b"), _entry(1, "rule d")])) == [
        True, True, False]


def test_budget_unit_survives_save_and_load(tmp_path, embedder) -> None:
    repo = WorldKnowledgeRepository(embedder, budget=1)
    asyncio.run(repo.add([_entry(0, "rule a"), _entry(0, "rule b")]))
    repo.commit(0)
    repo.save(tmp_path / "m")
    again = WorldKnowledgeRepository.load(tmp_path / "m", embedder)
    assert again.budget_unit == "episodes" and again.budget == 1 and len(again) == 2
    assert again.commits == [[0, 2]]
    assert asyncio.run(again.add([_entry(1, "rule z")])) == [False]
    assert len(again.truncated(1)) == 1 and again.truncated(1).commits == []
