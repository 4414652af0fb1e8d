"""`--perturb rename`: the shipped tables, and that renaming touches what the env says, never what it is."""

from __future__ import annotations

import random
import re

import pytest

from worldmind_local.perturb import RenamedAdapter, Renamer, rename_table
from worldmind_local.registry import BENCHMARKS

BENCHMARK_NAMES = ("eb_alfred", "eb_habitat", "eb_navigation")


def test_alfred_table_has_the_papers_32_types_all_real_and_all_renamed() -> None:
    from benchmarks.eb_alfred.typefacts import FIND_TYPES

    table = rename_table("eb_alfred")
    assert len(table) == 32
    assert set(table) <= set(FIND_TYPES)
    renamer = Renamer(table)
    for name, synonym in table.items():
        assert renamer(f"Cannot find {name}.") == f"Cannot find {synonym}."
        assert renamer(f"Cannot find {name.capitalize()}.") == f"Cannot find {synonym}."  # EB's "Butterknife"


@pytest.mark.parametrize("benchmark", BENCHMARK_NAMES)
def test_synonyms_name_no_other_type_of_the_benchmark(benchmark: str) -> None:
    """A synonym that were another type's name would make the feedback lie about which object it means."""
    table = rename_table(benchmark)
    renamer = Renamer(table)
    for synonym in table.values():
        assert renamer(synonym) == synonym, synonym
    assert len(set(map(str.casefold, table.values()))) == len(table)


def test_matching_is_whole_name_instances_plurals_and_spaced_forms() -> None:
    renamer = Renamer(rename_table("eb_alfred"))
    assert renamer("find a Cabinet_2") == "find a cupboard_2"
    assert renamer("a Potato near the Pot and two pots") == "a spud near the casserole and two casseroles"
    assert renamer("the butter knife, the ButterKnife") == "the spreader, the spreader"
    assert renamer("the bedroom and the potatoes") == "the bedroom and the spuds"
    habitat = Renamer(rename_table("eb_habitat"))
    assert habitat("Robot cannot reach. Refrigerator: closed. Cabinets: 7 closed.") == \
        "Robot cannot reach. Fridge: closed. Cupboards: 7 closed."


def _play(adapter, benchmark: str, n_steps: int = 25):
    """Reset on a generated task and take seeded random actions; the trace of what the env exposes."""
    base = BENCHMARKS.get(benchmark)
    task = base.generate_tasks(0, base.subsets[0], 2)[1]
    env = adapter.make_env("twin")
    obs = env.reset(task)
    trace = {"actions": list(env.actions), "states": [obs.state], "texts": [obs.text], "feedback": [],
             "outcome": []}
    rng = random.Random(7)
    for _ in range(n_steps):
        res = env.step(rng.randrange(len(env.actions)))
        trace["states"].append(res.observation.state)
        trace["texts"].append(res.observation.text)
        trace["feedback"].append(res.feedback)
        trace["outcome"].append((res.success, res.progress, res.invalid, res.done, res.end_reason))
        if res.done:
            break
    return trace


@pytest.mark.parametrize("benchmark", BENCHMARK_NAMES)
def test_rename_never_changes_an_action_name_or_the_state(benchmark: str) -> None:
    clean = _play(BENCHMARKS.get(benchmark), benchmark)
    renamed = _play(RenamedAdapter(BENCHMARKS.get(benchmark)), benchmark)
    assert renamed["actions"] == clean["actions"]          # the parser's names: untouched
    assert renamed["states"] == clean["states"]            # the simulator state: untouched
    assert renamed["outcome"] == clean["outcome"]          # success, progress, limits: untouched
    renamer = Renamer(rename_table(benchmark))
    assert renamed["feedback"] == [renamer(f) for f in clean["feedback"]]
    assert renamed["texts"] == [renamer(t) for t in clean["texts"]]


def test_feedback_really_changes_on_alfred() -> None:
    clean = _play(BENCHMARKS.get("eb_alfred"), "eb_alfred", 60)
    renamed = _play(RenamedAdapter(BENCHMARKS.get("eb_alfred")), "eb_alfred", 60)
    changed = [(a, b) for a, b in zip(clean["feedback"], renamed["feedback"], strict=True) if a != b]
    assert changed, "no feedback mentioned a renamed object in 60 random steps"
    names = rename_table("eb_alfred")
    for _, after in changed:
        assert not any(re.search(rf"(?<![A-Za-z]){n}(?![A-Za-z])", after) for n in names), after


def test_the_env_stays_picklable_for_env_workers() -> None:
    import pickle

    adapter = RenamedAdapter(BENCHMARKS.get("eb_alfred"))
    clone = pickle.loads(pickle.dumps(adapter))
    assert clone.name == "eb_alfred" and clone.renamer("the Mug") == "the stein"
