"""SimuRA (baselines.md §4): encoder, policy (n samples), clustering by action id, per-cluster memory
update / world model / critic (n samples), the reward-then-count-then-id choice, one action per step,
3-18 requests per step, and blindness to success/progress."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from worldmind_local.methods.simura import SimuRA, SimuRAConfig, cluster_samples, critic_score
from worldmind_local.registry import METHODS


def _sample(action_id: int, name: str = "x") -> str:
    return json.dumps({"think": f"try {action_id}", "action_id": action_id, "action_name": name})


def _tried(request: Any) -> str:
    """The intent a world-model request simulates (the line after its heading)."""
    text = request.messages[1]["content"]
    return text.split("## The action the robot tries next\n", 1)[1].split("\n", 1)[0]


def _world_model(good: int) -> Any:
    return lambda r: json.dumps({"next_state": "GOOD" if _tried(r).startswith(f"action id {good}:") else "BAD"})


def _critic(request: Any) -> list[str]:
    text = request.messages[1]["content"]
    imagined = text.split("(imagined, not observed)\n", 1)[1]
    verdict = ("success", "yes") if imagined.startswith("GOOD") else ("failure", "no")
    n = request.sampling.n
    return [json.dumps({"think": "t", "status": verdict[0], "on_the_right_track": verdict[1]})] * n


def _run(kit: Any, task: Any, script: dict[str, list[Any]], *, world: Any = None, seed: int = 7,
         good: int = 0, **config: Any) -> tuple[Any, Any]:
    defaults = {"encoder": json.dumps({"state": "the robot stands at the start"}),
                "memory_update": json.dumps({"memory_update": "noted"}),
                "world_model": _world_model(good), "critic": _critic, "planner": _sample(0, "find a Apple")}
    backend = kit.ScriptedBackend(script, defaults=defaults)
    method = SimuRA(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, seed=seed), config=method.config)
    rec = kit.run_method(method, task, world or kit.AppleWorld(max_steps=1), ctx)
    return rec, backend


def test_registered_with_the_reference_defaults() -> None:
    assert METHODS.get("simura") is SimuRA
    c = SimuRAConfig()
    assert (c.policy_samples, c.critic_samples, c.max_clusters) == (20, 20, 5)
    assert (c.policy_temperature, c.policy_top_p, c.critic_temperature, c.critic_top_p) == (1.0, 0.95, 1.0, 0.95)
    assert (c.module_temperature, c.module_top_p, c.n_shots, c.return_if_single) == (0.0, 0.5, 0, True)


def test_three_clusters_are_simulated_and_the_best_reward_beats_the_vote(kit, task) -> None:
    policy = [_sample(1), _sample(1), "garbage", _sample(1), _sample(0), _sample(2), _sample(9)]
    rec, backend = _run(kit, task, {"planner": [policy]}, policy_samples=7, critic_samples=4)
    roles = [c.role for c in rec.calls]
    assert len(roles) == 3 + 3 * 3  # encoder + policy + 3 x (memory, world model, critic) + real memory
    assert roles.count("world_model") == 3 and roles.count("critic") == 3 and roles.count("memory_update") == 4
    assert backend.of("planner")[0].sampling.n == 7 and backend.of("planner")[0].sampling.temperature == 1.0
    assert all(r.sampling.n == 4 and r.sampling.top_p == 0.95 for r in backend.of("critic"))
    assert all(r.sampling.temperature == 0.0 for role in ("encoder", "world_model", "memory_update")
               for r in backend.of(role))
    sim = rec.plans[0].extra["simura"]
    assert [(c["action_id"], c["count"]) for c in sim["clusters"]] == [(1, 3), (0, 1), (2, 1)]
    assert [s["usable"] for s in sim["samples"]] == [True, True, False, True, True, True, False]
    assert {s["action_id"]: s["reward"] for s in sim["simulations"]} == {1: 0.0, 0: 1.0, 2: 0.0}
    assert sim["chosen"] == 0 and [s.action_id for s in rec.trajectory] == [0]  # one action per step
    assert rec.plans[0].n_actions == 1


def test_one_cluster_is_taken_without_simulation(kit, task) -> None:
    rec, backend = _run(kit, task, {"planner": [[_sample(0)] * 3]}, policy_samples=3)
    assert [c.role for c in rec.calls] == ["encoder", "planner", "memory_update"]
    assert rec.method_stats["single_cluster_steps"] == 1 and "simulations" not in rec.plans[0].extra["simura"]


def test_at_most_max_clusters_and_ties_go_to_count_then_smallest_id(kit, task) -> None:
    policy = [_sample(3), _sample(2), _sample(2), _sample(1), _sample(0)]
    rec, _ = _run(kit, task, {"planner": [policy]}, good=-1, max_clusters=3, policy_samples=5, critic_samples=2)
    sim = rec.plans[0].extra["simura"]
    assert [c["action_id"] for c in sim["clusters"]] == [2, 0, 1]  # count first, then smallest id; 3 cut
    assert sim["chosen"] == 2  # every reward 0: the larger cluster wins
    assert len(rec.calls) == 3 + 3 * 3 <= 18


def test_the_request_count_stays_in_the_reference_range(kit, task) -> None:
    policy = [_sample(i % 6) for i in range(20)]
    rec, _ = _run(kit, task, {"planner": [policy]})
    assert len(rec.calls) == 18  # 5 clusters (6 distinct actions, top 5 kept)


def test_no_usable_policy_sample_follows_ebs_policy(kit, task) -> None:
    rec, backend = _run(kit, task, {"planner": [["{bad", _sample(42)]]}, policy_samples=2)
    assert [c.role for c in rec.calls][:2] == ["encoder", "planner"]
    assert rec.plans[0].status == "malformed" and rec.invalid_actions >= 1 and rec.trajectory[0].action_id == -1
    nav = dataclasses.replace(task, benchmark="eb_navigation")
    world = kit.AppleWorld(benchmark="eb_navigation", max_steps=1)
    rec, _ = _run(kit, nav, {"planner": [["{bad"]]}, world=world, policy_samples=1)
    assert rec.trajectory[0].substituted and rec.steps == 1


def test_unparseable_critic_samples_are_left_out_of_the_mean() -> None:
    ok = json.dumps({"think": "", "status": "failure", "on_the_right_track": "yes"})
    assert critic_score(ok) == 0.5 and critic_score("nope") is None
    assert critic_score(json.dumps({"status": "success", "on_the_right_track": "no"})) == 1.0
    clusters, log = cluster_samples([_sample(1), "x", _sample(1)], ["a", "b"], 5)
    assert [(c.action_id, c.count, c.first_sample) for c in clusters] == [(1, 2, 0)] and len(log) == 3


class _OtherProgress:
    """AppleWorld reporting different progress numbers: no module's prompt may change."""

    def __init__(self, kit: Any) -> None:
        self.inner = kit.AppleWorld(max_steps=3)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def step(self, action_id: int) -> Any:
        result = self.inner.step(action_id)
        return dataclasses.replace(result, progress=0.77 if result.progress else 0.0)


def test_no_module_sees_success_or_progress(kit, task) -> None:
    script = {"planner": [[_sample(0), _sample(0)], [_sample(1), _sample(2)], [_sample(2), _sample(3)]]}

    def prompts(world: Any) -> list[str]:
        rec, backend = _run(kit, task, dict(script), world=world, good=1, policy_samples=2, critic_samples=2)
        assert [s.action_id for s in rec.trajectory][:2] == [0, 1] and rec.trajectory[1].progress > 0
        return [f"{r.role}:{json.dumps(r.messages, default=str)}" for r in backend.requests]

    plain, other = prompts(kit.AppleWorld(max_steps=3)), prompts(_OtherProgress(kit))
    assert plain == other and {p.split(":", 1)[0] for p in plain} >= {"critic", "world_model", "encoder"}
    assert not any("0.5" in p or "task_success" in p or "progress=" in p for p in plain)


def test_same_seed_same_run_on_the_seeded_random_backend(kit, task) -> None:
    from collections import Counter

    from models.random_backend import RandomBackend

    def run(seed: int) -> tuple[list, list, list]:
        method = SimuRA({"policy_samples": 4, "critic_samples": 3})
        ctx = dataclasses.replace(kit.make_ctx(RandomBackend(), seed=seed), config=method.config)
        rec = kit.run_method(method, task, kit.AppleWorld(max_steps=3), ctx)
        return [c.request for c in rec.calls], [s.action_id for s in rec.trajectory], [c.key for c in rec.calls]

    first, again, other = run(3), run(3), run(4)
    assert first == again and first[0] != other[0]
    per_step = Counter(key.split(":")[1] for key in first[2])  # call keys carry the planning step
    assert per_step and all(2 <= n <= 18 for n in per_step.values())
