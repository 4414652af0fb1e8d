"""BoN (baselines.md §3): one planner request with n=N, one selector request when the candidates differ,
the deterministic fallbacks, blindness to success/progress, and EB's policy for unusable outputs."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from worldmind_local.methods.bon import BestOfN, BoNConfig, majority, merge_candidates
from worldmind_local.registry import METHODS


def _pick(index: int) -> str:
    return json.dumps({"analysis": "compared", "best_index": index})


def _run(kit: Any, task: Any, script: dict[str, list[Any]], *, world: Any = None, seed: int = 7,
         **config: Any) -> tuple[Any, Any]:
    backend = kit.ScriptedBackend(script, defaults={"selector": _pick(1)})
    method = BestOfN(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, seed=seed), config=method.config)
    rec = kit.run_method(method, task, world or kit.AppleWorld(), ctx)
    return rec, backend


def _plans(kit: Any) -> dict[str, str]:
    return {
        "solve": kit.plan_json(*kit.SOLVE, language_plan="solve"),
        "pick_first": kit.plan_json((1, "pick up the Apple", ""), language_plan="grab"),
        "find": kit.plan_json((0, "find a Apple", ""), language_plan="look"),
        "find_pick": kit.plan_json((0, "find a Apple", ""), (1, "pick up the Apple", ""), language_plan="fp"),
    }


def test_registered_with_the_spec_defaults() -> None:
    assert METHODS.get("bon") is BestOfN
    cfg = BoNConfig()
    assert (cfg.n_candidates, cfg.sample_temperature, cfg.selector_temperature, cfg.temperature) == (5, 0.7, 0.0, 0.0)
    assert cfg.selector_max_tokens == cfg.planner_max_tokens == 2048


def test_one_n_request_and_one_selector_request_per_planning_step(kit, task) -> None:
    p = _plans(kit)
    rec, backend = _run(kit, task, {
        "planner": [[p["pick_first"], p["solve"], "not json", p["solve"], p["find"]]],
        "selector": [_pick(2)],  # distinct candidates in first-sample order: pick_first, solve, find
    })
    planner, selector = backend.of("planner"), backend.of("selector")
    assert len(planner) == 1 and len(selector) == 1
    assert planner[0].sampling.n == 5 and planner[0].sampling.temperature == 0.7
    assert selector[0].sampling.n == 1 and selector[0].sampling.temperature == 0.0
    assert rec.success and [s.action_id for s in rec.trajectory] == [0, 1, 2, 3, 4]
    bon = rec.plans[0].extra["bon"]
    assert [s["status"] for s in bon["samples"]] == ["ok", "ok", "malformed", "ok", "ok"]
    assert [(d["ids"], d["count"]) for d in bon["distinct"]] == [([1], 1), ([0, 1, 2, 3, 4], 2), ([0], 1)]
    assert bon["pick"] == 1 and bon["selector"]["valid"] and bon["selector"]["called"]
    # the selector sees the three distinct candidates, numbered, with names from the action list
    user = selector[0].messages[1]["content"]
    assert "Candidate 3" in user and "Candidate 4" not in user and "1: pick up the Apple" in user
    assert [c.role for c in rec.calls] == ["planner", "selector"]


def test_the_selected_candidate_is_executed_and_agreement_skips_the_selector(kit, task) -> None:
    p = _plans(kit)
    rec, backend = _run(kit, task, {
        "planner": [[p["solve"], p["pick_first"], p["pick_first"]], [p["solve"]] * 3],
        "selector": [_pick(2)],  # the invalid pick-up: it runs, fails, and BoN re-plans
    }, n_candidates=3)
    assert [s.action_id for s in rec.trajectory] == [1, 0, 1, 2, 3, 4] and rec.trajectory[0].invalid
    assert len(backend.of("planner")) == 2 and len(backend.of("selector")) == 1
    assert rec.plans[1].extra["bon"]["selector"] == {"called": False}
    assert all(r.sampling.n == 3 for r in backend.of("planner"))


def test_unusable_selector_answers_fall_back_to_the_majority(kit, task) -> None:
    p = _plans(kit)
    for answer in ("no json here", _pick(9), json.dumps({"analysis": "x"})):
        rec, _ = _run(kit, task, {"planner": [[p["find"], p["solve"], p["solve"]]], "selector": [answer]},
                      n_candidates=3)
        bon = rec.plans[0].extra["bon"]
        assert not bon["selector"]["valid"] and bon["selector"]["fallback"] == "majority"
        assert bon["pick"] == 1 and rec.success  # "solve" has 2 votes against 1


def test_majority_ties_go_to_the_lowest_sample_index() -> None:
    plan = json.dumps({"language_plan": "", "executable_plan": [{"action_id": 2, "action_name": "x"}]})
    other = json.dumps({"language_plan": "", "executable_plan": [{"action_id": 1, "action_name": "y"}]})
    candidates, _ = merge_candidates([other, plan, plan, other], 6)
    assert [c.count for c in candidates] == [2, 2] and majority(candidates) == 0


def test_all_candidates_malformed_is_one_invalid_action_on_alfred(kit, task) -> None:
    rec, backend = _run(kit, task, {"planner": [["{bad", "no", ""]]}, n_candidates=3)
    assert not backend.of("selector")
    assert rec.plans[0].status == "malformed" and rec.planner_output_errors == 1 and rec.invalid_actions == 1
    assert rec.plans[0].extra["bon"]["fallback"] == "none_parseable"
    assert rec.trajectory[0].action_id == -1 and not rec.trajectory[0].env_step
    assert rec.end_reason == "empty_plan"  # the next step's default answer is an empty plan


def test_all_candidates_malformed_is_a_random_action_on_navigation(kit, task) -> None:
    world = kit.AppleWorld(benchmark="eb_navigation", max_steps=1)
    nav = dataclasses.replace(task, benchmark="eb_navigation")
    rec, _ = _run(kit, nav, {"planner": [["{bad", "nope"]]}, world=world, n_candidates=2)
    assert rec.plans[0].status == "malformed" and rec.trajectory[0].substituted and rec.steps == 1


def test_out_of_range_or_empty_candidates_get_ebs_rule(kit, task) -> None:
    bad_id = json.dumps({"language_plan": "", "executable_plan": [{"action_id": 99, "action_name": "x"}]})
    empty = kit.plan_json()
    rec, backend = _run(kit, task, {"planner": [[empty, bad_id, empty]]}, n_candidates=3)
    assert not backend.of("selector")
    bon = rec.plans[0].extra["bon"]
    assert [s["status"] for s in bon["samples"]] == ["empty", "invalid_first_id", "empty"]
    assert bon["fallback"] == "first_parseable" and bon["pick"] == 0
    assert rec.plans[0].status == "empty" and rec.end_reason == "empty_plan"
    # an empty candidate is dropped when a usable one exists
    p = _plans(kit)
    rec, backend = _run(kit, task, {"planner": [[empty, p["solve"]]]}, n_candidates=2)
    assert rec.success and not backend.of("selector")


class _OtherProgress:
    """AppleWorld reporting different progress numbers: what the selector sees must not change."""

    def __init__(self, kit: Any) -> None:
        self.inner = kit.AppleWorld()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def step(self, action_id: int) -> Any:
        result = self.inner.step(action_id)
        return dataclasses.replace(result, progress=0.77 if result.progress else 0.0)


def test_the_selector_never_sees_success_or_progress(kit, task) -> None:
    p = _plans(kit)

    def selector_texts(world: Any) -> list[str]:
        rec, backend = _run(kit, task, {
            "planner": [[p["find_pick"]] * 2, [p["solve"], p["find"]]],  # the 2nd step is after the pick-up
            "selector": [_pick(1)],
        }, world=world, n_candidates=2)
        assert rec.trajectory[1].progress > 0
        return [json.dumps(r.messages, default=str) for r in backend.of("selector")]

    plain, other = selector_texts(kit.AppleWorld()), selector_texts(_OtherProgress(kit))
    assert len(plain) == 1 and plain == other
    assert "0.5" not in plain[0] and "task_success" not in plain[0] and "progress=" not in plain[0]


def test_same_seed_same_run_on_the_seeded_random_backend(kit, task) -> None:
    from models.random_backend import RandomBackend

    def run(seed: int) -> tuple[list, list, list]:
        backend = RandomBackend()
        method = BestOfN({"n_candidates": 4})
        ctx = dataclasses.replace(kit.make_ctx(backend, seed=seed), config=method.config)
        rec = kit.run_method(method, task, kit.AppleWorld(), ctx)
        return ([c.request for c in rec.calls], [s.action_id for s in rec.trajectory],
                [pl.extra["bon"].get("pick") for pl in rec.plans])

    first, again, other = run(3), run(3), run(4)
    assert first == again and first[0] != other[0]
    assert len(first[0]) >= 2


def test_the_random_backend_answers_n_distinct_seeded_texts() -> None:
    import asyncio

    from models.base import ChatRequest, Sampling
    from models.random_backend import RandomBackend

    request = ChatRequest(messages=[{"role": "user", "content": "plan"}], sampling=Sampling(n=5, seed=3))
    first = asyncio.run(RandomBackend().complete([request]))[0].texts
    again = asyncio.run(RandomBackend().complete([request]))[0].texts
    assert len(first) == 5 and len(set(first)) == 5 and first == again
