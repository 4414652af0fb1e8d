"""EB-Navigation few-shot worked examples (benchmarks/eb_navigation/examples.py): count, determinism, replay in
the twin, exclusion of the evaluated episode, the skip string and its cascade."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks.eb_navigation import ADAPTER
from benchmarks.eb_navigation import examples as module
from benchmarks.eb_navigation.examples import POOL_SEED, POOL_SIZE, worked_examples
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
    env = ADAPTER.make_env("twin", images=False)
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
    examples = worked_examples(3, data_dir=data_dir)
    assert len(examples) == 3 and len({ex.task_id for ex in examples}) == 3
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
    first = worked_examples(3, data_dir=data_dir)
    assert worked_examples(3, data_dir=data_dir) == first
    _clear_caches()
    assert worked_examples(3, data_dir=data_dir) == first
    assert worked_examples(2, data_dir=data_dir) == first[:2]


def test_excluded_id_or_instruction_never_returned(data_dir: Path | None) -> None:
    base = worked_examples(3, data_dir=data_dir)
    by_id = worked_examples(3, data_dir=data_dir, exclude=[base[0].task_id])
    assert len(by_id) == 3 and base[0].task_id not in {ex.task_id for ex in by_id}
    # case, surrounding blanks and a trailing '.' do not matter
    shouted = f"  {base[1].instruction.strip().rstrip('.').upper()}. "
    by_text = worked_examples(3, data_dir=data_dir, exclude=[shouted])
    assert len(by_text) == 3 and base[1].task_id not in {ex.task_id for ex in by_text}
    target = norm(base[1].instruction)
    assert all(norm(ex.instruction) != target for ex in by_text)


def test_pool_size_caps_n_and_zero_gives_none() -> None:
    everything = worked_examples(100_000)
    assert 3 <= len(everything) < 100_000 and len({ex.task_id for ex in everything}) == len(everything)
    assert worked_examples(0) == []


def test_generated_pool_does_not_use_the_default_suite() -> None:
    default_ids = {t.id for t in ADAPTER.generate_tasks(0, "base", 50)}
    assert not default_ids & {ex.task_id for ex in worked_examples(100_000)}


def test_without_data_pack_falls_back_to_generated(tmp_path: Path) -> None:
    assert worked_examples(5, data_dir=tmp_path) == worked_examples(5)


def test_data_pack_examples_come_from_base_and_predict(eb_data_dir: Path) -> None:
    """The base targets are in view from the start, so no prediction skips; short, varied plans first."""
    examples = worked_examples(3, data_dir=eb_data_dir)
    assert all(ex.task_id.startswith("eb_navigation/base/") for ex in examples)
    assert all(a.predicted_state != SKIP_STRING for ex in examples for a in ex.actions)
    assert all(len(ex.actions) <= module.SHORT for ex in examples)
    assert len({a.action_id for a in examples[0].actions}) > 1
    assert len({norm(ex.instruction) for ex in examples}) == 3


def test_same_episode_in_another_subset_is_excluded(eb_data_dir: Path) -> None:
    """common_sense/i is base/i under another instruction: evaluating it removes the base example."""
    first = worked_examples(3, data_dir=eb_data_dir)[0]
    twin_id = first.task_id.replace("/base/", "/common_sense/")
    kept = worked_examples(3, data_dir=eb_data_dir, exclude=[twin_id])
    assert len(kept) == 3 and first.task_id not in {k.task_id for k in kept}


def test_same_target_type_is_excluded_with_the_instruction(eb_data_dir: Path) -> None:
    """EB-Navigation instructions name only the target type: excluding one drops that target everywhere."""
    first = worked_examples(3, data_dir=eb_data_dir)[0]
    kept = worked_examples(50, data_dir=eb_data_dir, exclude=[first.instruction])
    target = first.instruction.split(" the ")[1].split(" ")[0]
    assert kept and all(f" the {target} " not in k.instruction for k in kept)


def test_adapter_delegates_and_states_official_defaults(eb_data_dir: Path) -> None:
    assert isinstance(ADAPTER, BenchmarkAdapter)
    assert ADAPTER.default_n_shots == 3 and ADAPTER.default_top_k == 2
    assert ADAPTER.worked_examples(3, data_dir=eb_data_dir) == worked_examples(3, data_dir=eb_data_dir)
    assert ADAPTER.worked_examples(3) == worked_examples(3)
