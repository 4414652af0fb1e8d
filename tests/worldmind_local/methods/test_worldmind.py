"""WorldMind and its ablations as Methods: each variant changes which roles are called and what is produced."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

import pytest

from worldmind_local.methods.base import EpisodeContext, Method, MethodConfig
from worldmind_local.methods.worldmind import (
    ABLATIONS,
    WorldMind,
    WorldMindBaseline,
    WorldMindConfig,
    WorldMindGoalOnly,
    WorldMindNoVerifier,
    WorldMindProcessOnly,
)
from worldmind_local.records import EpisodeRecord


def _episode(kit: Any, task: Any, memory: Any, embedder: Any, cls: type, **config: Any) -> tuple:
    """Two plans: a wrong prediction (judged a mismatch), then the solution; the episode succeeds."""
    wrong = kit.plan_json((1, "pick up the Apple", "I am holding the Apple."))
    backend = kit.ScriptedBackend({
        "planner": [wrong, kit.plan_json(*kit.SOLVE)],
        "judge": [kit.verdict_json(False, "hand is empty")],
        "reflector": [json.dumps({"rules": ["Find the object before picking it up."]})],
        "distiller": [json.dumps({"workflow": "Find, pick, store."})],
    })
    method = cls(config)
    ctx = dataclasses.replace(kit.make_ctx(backend, memory, embedder), config=method.config)
    rec = kit.run_method(method, task, kit.AppleWorld(), ctx)
    return rec, backend


def test_full_worldmind_learns_both_kinds(kit, task, memory, embedder) -> None:
    rec, backend = _episode(kit, task, memory, embedder, WorldMind)
    assert isinstance(rec, EpisodeRecord) and rec.method == "worldmind" and rec.success
    assert [e["partition"] for e in rec.experience] == ["process", "goal"]
    assert len(backend.of("judge")) == 2 and len(backend.of("reflector")) == 1 and len(backend.of("distiller")) == 1
    assert memory.counts() == {"process": 1, "goal": 1}


def test_no_verifier_reflects_every_checked_prediction_without_a_judge(kit, task, memory, embedder) -> None:
    """The paper's controlled ablation 'WM w/o Verifier': Process Experience kept, validator gone."""
    rec, backend = _episode(kit, task, memory, embedder, WorldMindNoVerifier)
    assert not backend.of("judge") and rec.method_stats["judge_calls"] == 0
    assert len(backend.of("reflector")) == 2  # the first action of each of the two plans
    assert [e["partition"] for e in rec.experience] == ["process", "process", "goal"]
    assert rec.config["verifier"] is False and rec.method == "worldmind_no_verifier"


def test_goal_only_never_judges_reflects_or_retrieves_rules(kit, task, memory, embedder) -> None:
    calls: list[str] = []
    original = memory.retrieve
    memory.retrieve = lambda q, p, k, **kw: calls.append(p) or original(q, p, k, **kw)
    rec, backend = _episode(kit, task, memory, embedder, WorldMindGoalOnly)
    assert not backend.of("judge") and not backend.of("reflector") and memory.counts()["process"] == 0
    assert [e["partition"] for e in rec.experience] == ["goal"] and set(calls) == {"goal"}


def test_process_only_never_distills_or_retrieves_workflows(kit, task, memory, embedder) -> None:
    calls: list[str] = []
    original = memory.retrieve
    memory.retrieve = lambda q, p, k, **kw: calls.append(p) or original(q, p, k, **kw)
    rec, backend = _episode(kit, task, memory, embedder, WorldMindProcessOnly)
    assert not backend.of("distiller") and rec.method_stats["distillations"] == 0 and memory.counts()["goal"] == 0
    assert len(backend.of("judge")) == 2 and rec.method_stats["judge_mismatches"] == 1
    assert [e["partition"] for e in rec.experience] == ["process"] and set(calls) == {"process"}


def test_baseline_uses_no_memory_and_no_verifier(kit, task, memory, embedder) -> None:
    rec, backend = _episode(kit, task, memory, embedder, WorldMindBaseline)
    assert {r.role for r in backend.requests} == {"planner"}
    assert rec.experience == [] and rec.retrieval_seconds == [] and len(memory) == 0
    assert rec.success and rec.taxonomy == "success"
    assert "World Knowledge Repository" not in str(backend.of("planner")[0].messages[1]["content"])


def test_a_variant_fixes_its_switches(kit, task, memory, embedder) -> None:
    method = WorldMindBaseline({"goal_experience": True})
    assert method.config.goal_experience is False


def test_verify_every(kit, task, memory, embedder) -> None:
    rec, _ = _episode(kit, task, memory, embedder, WorldMind, verify="every")
    assert rec.method_stats["judge_calls"] == 6 and rec.config["verify"] == "every"


def test_no_memory_means_no_experience_even_when_switched_on(kit, task) -> None:
    rec, backend = _episode(kit, task, None, None, WorldMind)
    assert rec.experience == [] and not backend.of("reflector") and not backend.of("distiller")
    assert rec.method_stats["judge_calls"] == 2  # the verifier still runs and is recorded


def test_methods_satisfy_the_protocol_and_have_unique_names() -> None:
    assert all(isinstance(cls(), Method) for cls in ABLATIONS.values())
    assert sorted(ABLATIONS) == sorted(cls.name for cls in ABLATIONS.values())
    assert set(ABLATIONS) == {"worldmind", "worldmind_goal_only", "worldmind_process_only",
                              "worldmind_no_verifier", "worldmind_baseline"}


def test_method_config_rejects_bad_values() -> None:
    with pytest.raises(ValueError, match="verify"):
        WorldMindConfig(verify="sometimes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="abstract_with"):
        WorldMindConfig(abstract_with="pixels")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="top_k"):
        WorldMindConfig(top_k=-1)
    with pytest.raises(ValueError, match="extra"):
        WorldMindConfig(top_kk=1)  # type: ignore[call-arg]


def test_context_defaults() -> None:
    ctx = EpisodeContext(models={}, model_ids={}, memory=None, embedder=None)
    assert ctx.config == MethodConfig() and ctx.seed == 0
