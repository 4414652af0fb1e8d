"""The EB-Habitat twin: preconditions, exact feedback, limits, success, progress, observations."""

from __future__ import annotations

import pytest

from benchmarks.eb_habitat.twin import HabitatTwin
from worldmind_local.env import Env, UnknownActionError

OK = "Last action executed successfully."
BAD = "Last action is invalid."


def run(env: HabitatTwin, *names: str):
    return [env.step(env.action_id(n)) for n in names]


@pytest.fixture
def env(episode, make_task) -> HabitatTwin:
    twin = HabitatTwin()
    twin.reset(make_task(episode))
    return twin


def test_is_an_env_with_the_70_skills(env):
    assert isinstance(env, Env)
    assert len(env.actions) == 70 and env.max_steps == 30 and env.max_invalid == 10
    assert env.actions[0] == "navigate to the cabinet 7" and env.actions[69] == "close the cabinet 4"


def test_navigation_is_always_valid(env):
    for name in ("navigate to the sofa", "navigate to the sofa", "navigate to the cabinet 4"):
        (r,) = run(env, name)
        assert (r.feedback, r.invalid) == (OK, False)


def test_pick_needs_the_object_near_the_robot(env):
    (r,) = run(env, "pick up the apple")  # not navigated anywhere yet
    assert (
        r.feedback
        == BAD
        + " Robot cannot pick any object that is not near the robot. Navigate to other place to find the object."
    )
    assert r.invalid and env.world.held == -1
    r = run(env, "navigate to the sofa", "pick up the apple")[-1]
    assert r.invalid


def test_pick_then_pick_again_says_the_hand_is_full(env, names):
    ok, full = run(env, "navigate to the table 1", "pick up the apple", "pick up the apple")[1:]
    assert ok.feedback == "Last action executed successfully and you are holding apple."
    assert env.entities.names[env.world.held] == names.APPLE_T1
    assert (
        full.feedback
        == BAD
        + " Robot cannot pick any object when holding something. Please place the object before picking something."
    )


def test_pick_prefers_the_object_on_the_navigated_receptacle(episode, make_task, names):
    episode["rigid_objs"][0]["start_receptacle"] = names.COUNTER_LEFT  # first apple: within reach of the sink
    episode["name_to_receptacle"][names.APPLE_T1] = names.COUNTER_LEFT
    env = HabitatTwin()
    env.reset(make_task(episode))
    run(env, "navigate to the sink in the kitchen", "pick up the apple")
    assert env.entities.names[env.world.held] == names.APPLE_SINK
    run(env, "place at the right counter in the kitchen", "pick up the apple")  # none left on the sink itself
    assert env.entities.names[env.world.held] == names.APPLE_T1


def test_place_feedback_and_preconditions(env):
    (empty,) = run(env, "place at the sofa")
    assert (
        empty.feedback
        == BAD
        + " Robot cannot place any object when not holding something. Please pick the object before place it."
    )
    far = run(env, "navigate to the table 1", "pick up the apple", "place at the sofa")[-1]
    assert (
        far.feedback
        == BAD
        + " Robot cannot place any object that is not near the robot. Navigate to other place to find the object."
    )
    ok = run(env, "navigate to the sofa", "place at the sofa")[-1]
    assert ok.feedback == "Last action executed successfully and you are holding nothing."


def test_invalid_actions_do_not_change_the_state(env):
    run(env, "navigate to the table 1")
    before = env.world.snapshot()
    for name in ("place at the sofa", "open the refrigerator", "close the cabinet 7", "pick up the knife"):
        (r,) = run(env, name)
        assert r.invalid and env.world.snapshot() == before


def test_fridge_door_and_closed_container(env):
    (far,) = run(env, "open the refrigerator")
    assert (
        far.feedback
        == BAD + " Check whether the receptacle is already open or the robot is not near the receptacle."
    )
    shut = run(env, "navigate to the refrigerator", "pick up the knife")[-1]
    assert shut.invalid  # inside the closed fridge
    opened, again = run(env, "open the refrigerator", "open the refrigerator")
    assert opened.feedback == "Last action executed successfully and now refrigerator is open."
    assert again.invalid
    assert not run(env, "pick up the knife")[0].invalid
    run(env, "place at the refrigerator")
    closed, twice = run(env, "close the refrigerator", "close the refrigerator")
    assert closed.feedback == "Last action executed successfully and now refrigerator is closed."
    assert (
        twice.feedback
        == BAD + " Check whether the receptacle is already closed or the robot is not near the receptacle."
    )


def test_cabinet_feedback_and_drawer_contents(env, names):
    assert run(env, "navigate to the left drawer of the kitchen counter", "pick up the bowl")[-1].invalid
    opened = run(env, "open the cabinet 7")[0]
    assert opened.feedback == "Last action executed successfully and now cabinet 7 is open."
    assert not run(env, "pick up the bowl")[0].invalid
    assert env.entities.names[env.world.held] == names.BOWL
    assert (
        run(env, "close the cabinet 7")[0].feedback
        == "Last action executed successfully and now cabinet 7 is closed."
    )


def test_success_ends_the_episode_with_full_progress(env):
    results = run(
        env, "navigate to the table 1", "pick up the apple", "navigate to the sofa", "place at the sofa"
    )
    last = results[-1]
    assert (last.success, last.done, last.end_reason, last.progress) == (True, True, "success", 1.0)
    assert not any(r.success for r in results[:-1])
    with pytest.raises(RuntimeError):
        env.step(0)


def test_progress_counts_subgoals_once_reached(env):
    progress = [
        r.progress for r in run(env, "navigate to the table 1", "pick up the apple", "navigate to the sofa")
    ]
    assert progress == [0.25, 0.5, 1.0]  # at the sofa with the apple in hand, subgoals 3 and 4 hold
    # Wander off: reached subgoals stay reached.
    assert run(env, "navigate to the TV stand")[0].progress == 1.0


def test_progress_without_success_is_the_subgoal_fraction(episode, make_task, names):
    twin = HabitatTwin()
    goal = {"expr_type": "AND", "sub_exprs": [f"robot_at({names.SOFA})", f"holding({names.BOWL})"]}
    twin.reset(make_task(episode, goal_preds=goal))
    r = run(twin, "navigate to the table 1", "navigate to the sofa")[-1]
    assert r.progress == 0.25 and not r.success


def test_ten_invalid_actions_end_the_episode(env):
    results = run(env, *["place at the sofa"] * 10)
    assert [r.done for r in results] == [False] * 9 + [True]
    assert results[-1].end_reason == "max_invalid" and results[-1].info["num_invalid"] == 10


def test_thirty_steps_end_the_episode(env):
    results = run(env, *["navigate to the sofa"] * 30)
    assert not any(r.done for r in results[:-1])
    assert results[-1].done and results[-1].end_reason == "max_steps"


def test_observation_is_rendered_lazily_from_its_own_step(env):
    first = run(env, "navigate to the table 1")[0].observation
    run(env, "pick up the apple", "navigate to the sofa")
    text = first.text  # read after two more steps
    assert "Robot location: the table 1." in text and "Holding: nothing." in text
    assert "apple" in text.split("Objects within reach:")[1]
    assert first.state["location"].endswith("table_01") and first.state["holding"] is None


def test_observation_hides_closed_containers(env, names):
    obs = run(env, "navigate to the refrigerator push point")[0].observation
    assert "knife" not in obs.text and "the refrigerator (closed)" in obs.text
    obs = run(env, "open the refrigerator")[0].observation
    assert "knife" in obs.text and "Refrigerator: open." in obs.text
    assert obs.state["objects"][names.KNIFE] == names.FRIDGE


def test_start_predicates_set_doors_and_objects(episode, make_task, names):
    twin = HabitatTwin()
    starts = ["opened_fridge(fridge_push_point)", f"on_top({names.APPLE_T1},{names.SOFA})"]
    task = make_task(
        episode,
        start_preds=starts,
        goal_preds={"expr_type": "AND", "sub_exprs": ["closed_fridge(fridge_push_point)"]},
    )
    obs = twin.reset(task)
    assert (
        obs.state["doors"]["fridge_push_point"] == "open"
        and obs.state["objects"][names.APPLE_T1] == names.SOFA
    )
    r = run(twin, "navigate to the refrigerator push point", "close the refrigerator")[-1]
    assert r.success and r.end_reason == "success"


def test_unknown_actions(env):
    with pytest.raises(UnknownActionError, match="test/0"):
        env.action_id("fly to the moon")
    with pytest.raises(UnknownActionError):
        env.step(70)
