"""The loop's exact mechanics, with a scripted backend and a tiny scripted world."""

from __future__ import annotations

import asyncio
import json
from typing import Any

import pytest

from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.records import EpisodeRecord


def user_text(request: Any) -> str:
    content = request.messages[1]["content"]
    return content if isinstance(content, str) else content[-1]["text"]


def test_success_records_every_step_and_distills_goal_experience(kit, task, memory, embedder) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)],
                                   "distiller": [json.dumps({"workflow": "Find [OBJ], pick it, store it."})]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, memory, embedder))
    assert (rec.success, rec.progress, rec.steps, rec.end_reason, rec.taxonomy) == (True, 1.0, 5, "success", "success")
    assert [s.action_id for s in rec.trajectory] == [0, 1, 2, 3, 4]
    assert [s.progress for s in rec.trajectory] == [0.0, 0.5, 0.5, 0.5, 1.0]
    assert all(s.feedback == kit.OK for s in rec.trajectory)
    # predict-act-verify on the first action of the plan only
    assert rec.method_stats["judge_calls"] == 1 and [s.verified for s in rec.trajectory] == [True] + [False] * 4
    first = rec.trajectory[0]
    assert first.judge_verdict == "match" and first.actual_state.startswith("You are at Apple.")
    assert first.tokens["judge"].completion > 0
    # Goal Experience on success, with provenance, kept in the memory
    assert rec.method_stats["distillations"] == 1 and len(rec.method_stats["distillation_tokens"]) == 1
    [goal] = rec.experience
    assert goal["partition"] == "goal" and goal["kept"] is True
    assert goal["text"] == "Find [OBJ], pick it, store it."
    assert (goal["instruction"], goal["episode"], goal["task_id"], goal["run_id"]) == (
        task.instruction, 3, "apple-1", "run-test")
    assert "key_embedding" not in goal and "text_embedding" not in goal  # vectors live in the memory only
    assert [e.text for e in memory.entries("goal")] == [goal["text"]]
    assert rec.planner_calls == 1 and rec.tokens["planner"].prompt > 0 and rec.tokens["distiller"].completion > 0
    assert len(rec.retrieval_seconds) == 1 and rec.retrieval_seconds[0] >= 0
    EpisodeRecord.model_validate_json(rec.model_dump_json())  # the episodes.jsonl line round-trips


def test_cascading_skip_is_never_verified(kit, task) -> None:
    plan = kit.plan_json((0, "find a Apple", SKIP_STRING), (1, "pick up the Apple", "I am holding the Apple."))
    backend = kit.ScriptedBackend({"planner": [plan, kit.plan_json()]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, verify="every"))
    assert [(s.predicted_state, s.skipped, s.verified) for s in rec.trajectory] == [
        (SKIP_STRING, True, False), (SKIP_STRING, True, False)]
    assert rec.method_stats["judge_calls"] == 0 and not backend.of("judge")


def test_first_invalid_action_stops_the_plan_and_replans_with_history(kit, task) -> None:
    bad = kit.plan_json((1, "pick up the Apple", "I hold the Apple."), (2, "find a Fridge", "At the fridge."))
    backend = kit.ScriptedBackend({"planner": [bad, kit.plan_json(*kit.SOLVE)]})
    env = kit.AppleWorld()
    rec = kit.run_wm(task, env, kit.make_ctx(backend))
    assert env.step_calls[:2] == [1, 0]  # "find a Fridge" of the first plan never ran
    assert rec.trajectory[0].invalid and rec.invalid_actions == 1 and rec.success
    second = user_text(backend.of("planner")[1])
    assert ("Step 0, action id 1, pick up the Apple, env feedback: Last action is invalid. Cannot find Apple "
            "to pick up. Find the object before picking up it") in second
    # EB's language-only protocol: no state description reaches a text-only planner
    assert "You are at" not in second and "What you observe" not in second
    assert "no actions taken yet" in user_text(backend.of("planner")[0])


def test_symbolic_observation_is_shown_only_when_asked_for(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, observation="symbolic"))
    assert rec.observation == "symbolic"
    assert "You are at the start." in user_text(backend.of("planner")[0])
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend))
    assert rec.observation == "none" and "You are at" not in user_text(backend.of("planner")[0])


@pytest.mark.parametrize("verify,expected", [("first", [1]), ("every", [1, 2, 3, 4, 5])])
def test_verify_first_versus_every(kit, task, verify: str, expected: list[int]) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, verify=verify))
    assert [s.step for s in rec.trajectory if s.verified] == expected
    assert rec.method_stats["judge_calls"] == len(expected) == len(backend.of("judge"))


def test_unreadable_judge_defaults_to_match_and_is_counted(kit, task, memory, embedder) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)], "judge": ["they look similar"]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, memory, embedder))
    step = rec.trajectory[0]
    assert (step.judge_verdict, step.judge_unparseable) == ("match", True)
    assert (rec.method_stats["judge_calls"], rec.method_stats["judge_unparseable"], rec.method_stats["judge_mismatches"], rec.method_stats["reflections"]) == (1, 1, 0, 0)
    assert not backend.of("reflector") and not memory.entries("process")


def test_mismatch_reflects_into_process_experience_with_provenance(kit, task, memory, embedder) -> None:
    wrong = kit.plan_json((1, "pick up the Apple", "I am holding the Apple."))
    backend = kit.ScriptedBackend({
        "planner": [wrong, kit.plan_json(*kit.SOLVE)],
        "judge": [kit.verdict_json(False, "Predicted holding the Apple, but the hand is empty.")],
        "reflector": [json.dumps({"rules": ["Find an object before picking it up.", "Keep the hand free."]})],
    })
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, memory, embedder))
    step = rec.trajectory[0]
    assert (step.judge_verdict, step.rules) == ("mismatch", ["Find an object before picking it up.",
                                                             "Keep the hand free."])
    assert rec.method_stats["reflections"] == 1 and rec.method_stats["judge_mismatches"] == 1 and rec.method_stats["reflection_tokens"][0] > 0
    process = [e for e in rec.experience if e["partition"] == "process"]
    assert [e["text"] for e in process] == step.rules and all(e["kept"] for e in process)
    entry = process[0]
    assert entry == {**entry, "benchmark": "eb_alfred", "subset": "base", "episode": 3, "task_id": "apple-1",
                     "step": 1, "action": "pick up the Apple", "predicted_state": "I am holding the Apple.",
                     "judge_reason": "Predicted holding the Apple, but the hand is empty.",
                     "planner_model": "scripted/planner", "judge_model": "scripted/judge", "run_id": "run-test"}
    assert entry["actual_state"].startswith("You are at the start. Your hand is empty.")
    # the reflector saw the failed step's context
    reflector_prompt = user_text(backend.of("reflector")[0])
    assert "Cannot find Apple to pick up" in reflector_prompt and "I am holding the Apple." in reflector_prompt
    # Process Experience is retrieved once, at the episode's start (official code): the episode's own
    # new rules never reach its later planner calls, and the method never wrote the memory itself
    assert "Find an object before picking it up." not in user_text(backend.of("planner")[1])
    assert rec.plans[1].extra["retrieved_process"] == [] and rec.retrieved_ids == []


def test_per_call_process_retrieval_sees_the_episodes_own_rules(kit, task, memory, embedder) -> None:
    wrong = kit.plan_json((1, "pick up the Apple", "I am holding the Apple."))
    backend = kit.ScriptedBackend({
        "planner": [wrong, kit.plan_json(*kit.SOLVE)],
        "judge": [kit.verdict_json(False, "hand is empty")],
        "reflector": [json.dumps({"rules": ["Find an object before picking it up."]})],
    })
    ctx = kit.make_ctx(backend, memory, embedder, process_retrieval="call")
    rec = kit.run_wm(task, kit.AppleWorld(), ctx)
    assert "1. Find an object before picking it up." in user_text(backend.of("planner")[1])
    assert rec.plans[1].extra["retrieved_process"] == [rec.experience[0]["id"]]
    assert len(memory.entries("process")) == 1  # committed once, by the runner (here: run_method)


def test_top_k_and_goal_self_exclusion_are_passed_to_memory(kit, task, memory, embedder) -> None:
    from worldmind_local.memory import ExperienceEntry

    def entry(partition: str, text: str, instruction: str) -> ExperienceEntry:
        return ExperienceEntry(partition=partition, text=text, instruction=instruction, benchmark="eb_alfred",
                               subset="base", episode=0, task_id="old")

    asyncio.run(memory.add([
        entry("goal", "Workflow from the very same task.", task.instruction),
        entry("goal", "Workflow A.", "Put a pear in the fridge."),
        entry("goal", "Workflow B.", "Heat a potato."),
        entry("process", "Rule A.", task.instruction),
        entry("process", "Rule B.", "Slice bread."),
    ]))
    calls: list[tuple] = []
    original = memory.retrieve

    def spy(query, partition, k, *, exclude_instruction=None):
        calls.append((partition, k, exclude_instruction))
        return original(query, partition, k, exclude_instruction=exclude_instruction)

    memory.retrieve = spy
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, memory, embedder, top_k=1))
    assert sorted(calls) == [("goal", 1, task.instruction), ("process", 1, None)]
    prompt = user_text(backend.of("planner")[0])
    assert "Workflow from the very same task." not in prompt
    assert "Rule A." in prompt and "Rule B." not in prompt  # top-1 process: the identical instruction
    assert len(rec.plans[0].extra["retrieved_goal"]) == 1 and len(rec.plans[0].extra["retrieved_process"]) == 1


def test_empty_plan_ends_the_episode(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(language_plan="I am done.")]})
    env = kit.AppleWorld()
    rec = kit.run_wm(task, env, kit.make_ctx(backend))
    assert (rec.end_reason, rec.taxonomy, rec.steps, rec.empty_plans) == ("empty_plan", "wrong_termination", 0, 1)
    assert env.step_calls == [] and rec.plans[0].status == "empty" and len(backend.of("planner")) == 1


def test_malformed_planner_json_is_an_invalid_action_without_a_step(kit, task) -> None:
    """EB-ALFRED/Habitat: +1 invalid action and planner_output_error, no env step, no history line."""
    backend = kit.ScriptedBackend({"planner": ["I will find the apple first."] * 3})
    env = kit.AppleWorld(max_invalid=3)
    rec = kit.run_wm(task, env, kit.make_ctx(backend))
    assert env.step_calls == [] and rec.steps == 0
    assert (rec.planner_output_errors, rec.invalid_actions, rec.end_reason, rec.taxonomy) == (
        3, 3, "max_invalid", "invalid_action_end")
    assert [(s.action_id, s.action_name, s.env_step, s.invalid) for s in rec.trajectory] == [
        (-1, "invalid action", False, True)] * 3
    assert all(p.status == "malformed" and p.raw == "I will find the apple first." for p in rec.plans)
    assert all("no actions taken yet" in user_text(r) for r in backend.of("planner"))


def test_malformed_outputs_and_invalid_steps_share_the_invalid_limit(kit, task) -> None:
    bad_step = kit.plan_json((1, "pick up the Apple", ""))
    backend = kit.ScriptedBackend({"planner": ["{oops", bad_step, "{oops"]})
    rec = kit.run_wm(task, kit.AppleWorld(max_invalid=3), kit.make_ctx(backend))
    assert (rec.invalid_actions, rec.steps, rec.end_reason) == (3, 1, "max_invalid")


def test_out_of_range_ids_follow_embodiedbench(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [
        kit.plan_json((99, "fly", "")),                           # first id out of range: one invalid action
        kit.plan_json((0, "find a Apple", ""), (42, "x", ""), (1, "pick up the Apple", "")),  # truncated
        kit.plan_json(),
    ]})
    env = kit.AppleWorld()
    rec = kit.run_wm(task, env, kit.make_ctx(backend))
    assert env.step_calls == [0]
    assert rec.plans[0].status == "invalid_id" and rec.planner_output_errors == 0 and rec.invalid_actions == 1


def test_action_id_wins_over_a_mismatching_name(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json((0, "open the Fridge", "")), kit.plan_json()]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend))
    step = rec.trajectory[0]
    assert (step.action_id, step.action_name, step.planned_name) == (0, "find a Apple", "open the Fridge")


def test_navigation_substitutes_a_seeded_random_action(kit, task) -> None:
    """EB-Navigation: unparseable output and an empty plan each execute a random action; an out-of-range id
    goes to the env as it is (EB's env answers it with THOR's Done)."""
    def episode(seed: int) -> tuple[EpisodeRecord, list[int]]:
        backend = kit.ScriptedBackend({"planner": ["garbage", kit.plan_json(), kit.plan_json((77, "x", "p"))]},
                                      defaults={"planner": "garbage"})
        env = kit.AppleWorld(benchmark="eb_navigation", max_steps=3, max_invalid=None)
        return kit.run_wm(task, env, kit.make_ctx(backend, seed=seed)), env.step_calls

    rec, calls = episode(seed=1)
    assert rec.steps == 3 and len(calls) == 3 and calls[2] == 77
    assert all(s.substituted and s.env_step and not s.verified for s in rec.trajectory[:2])
    last = rec.trajectory[2]
    assert (last.action_id, last.substituted, last.feedback) == (77, False, "Last action Done executed successfully.")
    assert [p.status for p in rec.plans] == ["malformed", "empty", "ok"]
    assert rec.planner_output_errors == 1 and rec.empty_plans == 1
    assert episode(seed=1)[1] == calls
    assert any(episode(seed=s)[1] != calls for s in range(2, 8))


def test_step_limit_is_a_timeout(kit, task) -> None:
    loop_plan = kit.plan_json((0, "find a Apple", ""), (2, "find a Fridge", ""))
    backend = kit.ScriptedBackend(defaults={"planner": loop_plan})
    rec = kit.run_wm(task, kit.AppleWorld(max_steps=5), kit.make_ctx(backend))
    assert (rec.steps, rec.end_reason, rec.taxonomy, rec.planner_calls) == (5, "max_steps", "step_limit", 3)


def test_seeds_are_deterministic_per_call(kit, task, memory, embedder) -> None:
    def episode(seed: int) -> tuple[list[int | None], EpisodeRecord]:
        wrong = kit.plan_json((1, "pick up the Apple", "I am holding the Apple."))
        backend = kit.ScriptedBackend({"planner": [wrong, kit.plan_json(*kit.SOLVE)],
                                       "judge": [kit.verdict_json(False, "hand empty")]})
        mem = type(memory)(embedder)
        rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, mem, embedder, seed=seed))
        return [r.sampling.seed for r in backend.requests], rec

    seeds, rec = episode(5)
    again, rec2 = episode(5)
    assert seeds == again and len(set(seeds)) == len(seeds) == 6  # 2 planner, 2 judge, reflector, distiller
    strip = {"wall_seconds", "retrieval_seconds", "plans", "trajectory"}
    assert rec.model_dump(exclude=strip) == rec2.model_dump(exclude=strip)
    assert episode(6)[0] != seeds


def test_context_overflow_ends_the_episode_as_an_error(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.ContextLengthError("prompt of 9000 tokens > 8192")]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend))
    assert (rec.end_reason, rec.taxonomy, rec.success) == ("context_length", "error", False)
    assert "9000" in rec.error


def test_a_success_stays_a_success_when_its_distillation_overflows(kit, task, memory, embedder) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)],
                                   "distiller": [kit.ContextLengthError("trajectory too long")]})
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, memory, embedder))
    assert (rec.success, rec.end_reason, rec.taxonomy, rec.error) == (True, "success", "success",
                                                                      "trajectory too long")
    assert rec.experience == []


def test_vlm_abstraction_and_planner_images(kit, task) -> None:
    backend = kit.ScriptedBackend({
        "planner": [kit.plan_json(*kit.SOLVE)],
        "summarizer": [json.dumps({"state_before": "Robot at start.", "state_after": "Robot at the apple."})],
    }, vision=True)
    rec = kit.run_wm(task, kit.AppleWorld(with_images=True), kit.make_ctx(backend, abstract_with="vlm"))
    [summary] = backend.of("summarizer")
    parts = summary.messages[1]["content"]
    assert [p["type"] for p in parts] == ["image", "image", "text"] and "find a Apple" in parts[2]["text"]
    assert rec.trajectory[0].actual_state == "Robot at the apple." and rec.method_stats["summarizer_calls"] == 1
    assert "Robot at the apple." in user_text(backend.of("judge")[0])
    assert backend.of("planner")[0].messages[1]["content"][0]["type"] == "image"


def test_text_abstraction_and_no_images_for_a_text_planner(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]})
    rec = kit.run_wm(task, kit.AppleWorld(with_images=True), kit.make_ctx(backend))
    assert isinstance(backend.of("planner")[0].messages[1]["content"], str)
    assert not backend.of("summarizer") and rec.trajectory[0].actual_state.startswith("You are at Apple.")


def test_vlm_abstraction_falls_back_to_text_without_images(kit, task) -> None:
    backend = kit.ScriptedBackend({"planner": [kit.plan_json(*kit.SOLVE)]}, vision=True)
    rec = kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(backend, abstract_with="vlm"))
    assert not backend.of("summarizer") and rec.trajectory[0].actual_state.startswith("You are at Apple.")


def test_vlm_abstraction_with_a_text_only_summarizer_is_refused(kit, task) -> None:
    with pytest.raises(ValueError, match="text-only"):
        kit.run_wm(task, kit.AppleWorld(), kit.make_ctx(kit.ScriptedBackend(), abstract_with="vlm"))
