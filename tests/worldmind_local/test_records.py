from __future__ import annotations

import json

import pytest

from worldmind_local.metrics import stream_metrics
from worldmind_local.records import (
    END_REASONS,
    TAXONOMY,
    EpisodeRecord,
    PlanRecord,
    StepRecord,
    TokenCount,
    taxonomy_label,
)


@pytest.mark.parametrize("success,end,label", [
    (True, "success", "success"),
    (False, "max_invalid", "invalid_action_end"),
    (False, "max_steps", "step_limit"),
    (False, "empty_plan", "wrong_termination"),
    (False, "planner_limit", "wrong_termination"),
    (False, "env_done", "wrong_termination"),
    (False, "context_length", "error"),
    (False, "error", "error"),
])
def test_taxonomy(success: bool, end: str, label: str) -> None:
    assert end in END_REASONS and label in TAXONOMY
    assert taxonomy_label(success, end) == label


def _record() -> EpisodeRecord:
    rec = EpisodeRecord(task_id="t", benchmark="eb_habitat", subset="base", index=4, instruction="Move the bowl.",
                        task_type="rearrange", method="worldmind", success=True, progress=1.0, steps=2,
                        end_reason="success", taxonomy="success",
                        method_stats={"judge_calls": 1, "reflections": 1, "distillations": 1},
                        retrieval_seconds=[0.0001, 0.0002])
    rec.add_tokens("reflector", 100, 20, 0.5)
    rec.add_tokens("reflector", 10, 2, 0.25)
    rec.add_tokens("distiller", 40, 10, 0.1)
    rec.plans.append(PlanRecord(index=0, env_step=0, status="ok", tokens=TokenCount(prompt=5, completion=6)))
    rec.trajectory.append(StepRecord(step=1, plan_index=0, action_id=3, action_name="navigate to the table 1",
                                     feedback="Last action executed successfully.", judge_verdict="match"))
    rec.experience.append({"id": "abc", "partition": "goal", "text": "w", "kept": True})
    return rec


def test_every_role_has_a_token_counter_and_tokens_add_up() -> None:
    rec = _record()
    assert set(rec.tokens) == {"planner", "judge", "reflector", "distiller", "summarizer"}
    assert rec.tokens["reflector"].model_dump() == {"prompt": 110, "completion": 22}
    assert rec.tokens["reflector"].total == 132 and rec.latency_s["reflector"] == 0.75


def test_record_round_trips_through_a_jsonl_line() -> None:
    rec = _record()
    line = json.dumps(rec.model_dump(mode="json"))
    assert EpisodeRecord.model_validate_json(line) == rec


def test_records_reject_unknown_fields() -> None:
    data = _record().model_dump(mode="json") | {"surprise": 1}
    with pytest.raises(ValueError, match="surprise"):
        EpisodeRecord.model_validate(data)


def test_metrics_read_the_record_fields() -> None:
    metrics = stream_metrics([_record().model_dump(mode="json")])
    assert metrics["SR"] == 100.0 and metrics["GC"] == 100.0 and metrics["taxonomy"]["success"] == 1
    assert metrics["tokens_per_reflection"] == 132 and metrics["tokens_per_distillation"] == 50
    assert metrics["retrieval_ms_per_step"] == pytest.approx(0.15) and metrics["experience_kept"] == 1
