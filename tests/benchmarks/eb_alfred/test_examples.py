"""EB-ALFRED few-shot worked examples (benchmarks/eb_alfred/examples.py): count, determinism, replay in
the twin, exclusion of the evaluated episode, the skip string and its cascade."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.eb_alfred import ADAPTER
from benchmarks.eb_alfred import examples as module
from benchmarks.eb_alfred.data import load_pack
from benchmarks.eb_alfred.examples import POOL_SEED, POOL_SIZE, worked_examples
from worldmind_local.agent.plan import SKIP_STRING
from worldmind_local.env import BenchmarkAdapter, Task, WorkedExample
from worldmind_local.examples import norm


def _clear_caches() -> None:
    for value in vars(module).values():
        if hasattr(value, "cache_clear"):
            value.cache_clear()


def _tasks_by_id(data_dir: Path | None) -> dict[str, Task]:
    if data_dir is None:
        return {t.id: t for t in ADAPTER.generate_tasks(POOL_SEED, "base", POOL_SIZE)}
    return {t.id: t for s in ADAPTER.subsets for t in ADAPTER.load_tasks(data_dir, s)}


def _check_replays(examples: list[WorkedExample], tasks: dict[str, Task]) -> None:
    """Every (id, name) pair is valid in that example's own episode and gives the recorded feedback."""
    env = ADAPTER.make_env("twin")
    for ex in examples:
        task = tasks[ex.task_id]
        assert ex.instruction == task.instruction
        env.reset(task)
        result = None
        for action in ex.actions:
            assert env.actions[action.action_id] == action.action_name, (ex.task_id, action)
            result = env.step(action.action_id)
            assert not result.invalid and result.feedback == action.feedback, (ex.task_id, action)
        assert result is not None and result.success, ex.task_id


def _check_predictions(ex: WorkedExample) -> None:
    """Skips only with the cascading rule: once skipped, every later action skips too."""
    skipping = False
    for action in ex.actions:
        if action.predicted_state == SKIP_STRING:
            skipping = True
        else:
            assert not skipping, (ex.task_id, action)
            assert 0 < len(action.predicted_state) <= 200 and "Exploration phase" not in action.predicted_state


@pytest.fixture(params=["generated", "data"])
def data_dir(request: pytest.FixtureRequest) -> Path | None:
    return None if request.param == "generated" else request.getfixturevalue("eb_data_dir")


def test_returns_n_valid_examples(data_dir: Path | None) -> None:
    examples = worked_examples(10, data_dir=data_dir)
    assert len(examples) == 10 and len({ex.task_id for ex in examples}) == 10
    assert all(0 < len(ex.actions) <= module.MAX_ACTIONS and ex.reasoning and ex.language_plan for ex in examples)
    _check_replays(examples, _tasks_by_id(data_dir))
    for ex in examples:
        _check_predictions(ex)


def test_whole_pool_replays_and_cascades(data_dir: Path | None) -> None:
    pool = worked_examples(100_000, data_dir=data_dir)
    _check_replays(pool, _tasks_by_id(data_dir))
    for ex in pool:
        _check_predictions(ex)


def test_deterministic_and_cached(data_dir: Path | None) -> None:
    first = worked_examples(10, data_dir=data_dir)
    assert worked_examples(10, data_dir=data_dir) == first
    _clear_caches()
    assert worked_examples(10, data_dir=data_dir) == first
    assert worked_examples(4, data_dir=data_dir) == first[:4]


def test_excluded_id_or_instruction_never_returned(data_dir: Path | None) -> None:
    base = worked_examples(10, data_dir=data_dir)
    by_id = worked_examples(10, data_dir=data_dir, exclude=[base[0].task_id])
    assert len(by_id) == 10 and base[0].task_id not in {ex.task_id for ex in by_id}
    # case, surrounding blanks and a trailing '.' do not matter
    shouted = f"  {base[1].instruction.strip().rstrip('.').upper()}. "
    by_text = worked_examples(10, data_dir=data_dir, exclude=[shouted])
    assert len(by_text) == 10 and base[1].task_id not in {ex.task_id for ex in by_text}
    target = norm(base[1].instruction)
    assert all(norm(ex.instruction) != target for ex in by_text)


def test_pool_size_caps_n_and_zero_gives_none() -> None:
    everything = worked_examples(100_000)
    assert 10 <= len(everything) < 100_000 and len({ex.task_id for ex in everything}) == len(everything)
    assert worked_examples(0) == []


def test_generated_pool_does_not_use_the_default_suite() -> None:
    default_ids = {t.id for t in ADAPTER.generate_tasks(0, "base", 50)}
    assert not default_ids & {ex.task_id for ex in worked_examples(100_000)}


def test_without_data_pack_falls_back_to_generated(tmp_path: Path) -> None:
    assert worked_examples(5, data_dir=tmp_path) == worked_examples(5)


def test_data_pack_examples_come_from_base_with_predictions(eb_data_dir: Path) -> None:
    examples = worked_examples(10, data_dir=eb_data_dir)
    assert all(ex.task_id.startswith("eb_alfred/base/") for ex in examples)
    assert len({_task_type(ex.task_id, eb_data_dir) for ex in examples}) >= 4
    assert examples[0].actions[0].predicted_state != SKIP_STRING  # the pool puts grounded plans first
    assert any(a.predicted_state == SKIP_STRING for ex in examples for a in ex.actions)


def _task_type(task_id: str, data_dir: Path) -> str:
    _, subset, index = task_id.split("/")
    return ADAPTER.load_tasks(data_dir, subset)[int(index)].task_type


def test_same_trial_in_another_subset_is_excluded(eb_data_dir: Path) -> None:
    """An evaluated episode of another subset on the same ALFRED trial removes the base example."""
    pack = load_pack(eb_data_dir)
    examples = worked_examples(10, data_dir=eb_data_dir)
    trial_of = {f"eb_alfred/{s}/{i}": e["task"] for s, entries in pack.splits.items() for i, e in enumerate(entries)}
    for ex in examples:
        twin_id = next((k for k, t in trial_of.items() if t == trial_of[ex.task_id] and "/base/" not in k), None)
        if twin_id is not None:
            break
    else:
        pytest.fail("no example shares its trial with another subset")
    kept = worked_examples(10, data_dir=eb_data_dir, exclude=[twin_id])
    assert len(kept) == 10 and ex.task_id not in {k.task_id for k in kept}
    assert all(trial_of[k.task_id] != trial_of[ex.task_id] for k in kept)


def test_adapter_delegates_and_states_official_defaults(eb_data_dir: Path) -> None:
    assert isinstance(ADAPTER, BenchmarkAdapter)
    assert ADAPTER.default_n_shots == 10 and ADAPTER.default_top_k == 2
    assert ADAPTER.worked_examples(3, data_dir=eb_data_dir) == worked_examples(3, data_dir=eb_data_dir)
    assert ADAPTER.worked_examples(3) == worked_examples(3)
