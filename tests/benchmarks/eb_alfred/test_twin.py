"""The twin's skills, exact feedback strings, limits and progress, on the hand-written kitchen."""

from __future__ import annotations

import pytest

from worldmind_local.env import UnknownActionError

OK = "Last action executed successfully."
BAD = "Last action is invalid. "


def state_of(env):
    """Everything a step may change (the world lists and scalars), for no-change checks."""
    w = env._world
    return (list(w.parent), list(w.pos), list(w.is_open), list(w.is_on), list(w.active), list(w.also_in),
            w.heated, w.cooled, w.cleaned, w.holding, w.agent, w.location)


@pytest.mark.parametrize(
    ("setup", "action", "message"),
    [
        ((), "pick up the Apple", "Apple is not visible because it is in CounterTop. Go there to pick the object instead."),
        ((), "put down the object in hand", "Robot is not holding any object"),
        ((), "drop the object in hand", "Robot is not holding any object"),
        (("find a Fridge",), "put down the object in hand", "Robot is not holding any object"),
        (("find a Mug",), "pick up the Mug", "Mug is not visible because it is in Fridge. Go there to pick the object instead."),
        ((), "open the Fridge", "Open action failed."),
        (("find a Fridge", "open the Fridge"), "open the Fridge", "Open action failed. The Fridge is already open"),
        (("find a Fridge",), "close the Fridge", "Close action failed. The Fridge is already closed"),
        ((), "turn on the Microwave", "Turn on action failed"),
        (("find a Microwave", "open the Microwave"), "turn on the Microwave", "Turn on action failed"),
        (("find a Microwave",), "turn off the Microwave", "Turn off action failed"),
        (("find a Apple",), "slice the Apple", "Slice action failed"),
        (("find a Knife", "pick up the Knife", "find a Apple"), "pick up the Apple", "Robot is currently holding Knife"),
        ((), "find a Bed", "Cannot find Bed. This object may not exist in this scene. Try to explore other instances instead."),
        ((), "find a CoffeeTable", "Cannot find Coffeetable. This object may not exist in this scene. Try to explore other instances instead."),
        ((), "pick up the SaltShaker", "Cannot find Saltshaker to pick up. Find the object before picking up it"),
        ((), "open the Safe", "Cannot find Safe to open. Find the object before opening it"),
        ((), "close the Drawer", "Cannot find Drawer to close"),
        ((), "turn on the FloorLamp", "Cannot find Floorlamp to turn on"),
        ((), "turn off the FloorLamp", "Cannot find Floorlamp to turn off"),
        ((), "slice the Bread", "Cannot find Bread to slice"),
        (("find a Cabinet",), "close the Cabinet", "Close action failed. The Cabinet is already closed"),
        ((), "open the Cabinet_2", "Open action failed."),
    ],
)
def test_precondition_violation_gives_eb_message_and_changes_nothing(twin, make_task, run, setup, action, message):
    twin.reset(make_task())
    for a in setup:
        assert run(twin, a).feedback == OK, a
    before = state_of(twin)
    result = run(twin, action)
    assert result.feedback == BAD + message
    assert result.invalid and not result.success
    assert state_of(twin) == before


def test_put_into_closed_receptacle_fails_and_third_time_drops(twin, make_task, run):
    twin.reset(make_task())
    run(twin, "find a Knife", "pick up the Knife", "find a Fridge")
    fail = BAD + ("Putting the object on Fridge failed. First check whether the receptacle is open or not. "
                  "Also try other instances of the receptacle")
    assert run(twin, "put down the object in hand").feedback == fail
    assert run(twin, "put down the object in hand").feedback == fail
    assert twin._world.holding >= 0
    third = run(twin, "put down the object in hand")
    assert third.feedback == fail + ". The robot dropped the object instead."
    assert third.invalid and twin._world.holding == -1


def test_pick_and_place_success_and_progress(twin, make_task, run):
    obs = twin.reset(make_task(parent="Fridge"))
    assert "Location: the starting position" in obs.text
    result = run(twin, "find a Apple", "pick up the Apple", "find a Fridge", "open the Fridge")
    assert result.progress == 0.0 and not result.done
    done = run(twin, "put down the object in hand")
    assert done.success and done.progress == 1.0 and done.done and done.end_reason == "success"
    with pytest.raises(RuntimeError):
        run(twin, "find a Fridge")


def test_progress_follows_current_state(twin, make_task, run):
    twin.reset(make_task("pick_two_obj_and_place", parent="Fridge"))
    run(twin, "find a Fridge", "open the Fridge", "find a Apple", "pick up the Apple", "find a Fridge")
    placed = run(twin, "put down the object in hand")
    assert placed.progress == 0.5 and not placed.success
    taken_back = run(twin, "pick up the Apple")
    assert taken_back.feedback == OK and taken_back.progress == 0.0


def test_ten_invalid_actions_end_the_episode(twin, make_task, run):
    twin.reset(make_task())
    for k in range(1, 10):
        r = run(twin, "find a Bed")
        assert not r.done, k
    last = run(twin, "find a Bed")
    assert last.done and last.end_reason == "max_invalid" and twin.invalid == 10


def test_thirty_step_limit(twin, make_task, run):
    twin.reset(make_task())
    for k in range(1, 30):
        assert not run(twin, "find a CounterTop").done, k
    last = run(twin, "find a CounterTop")
    assert last.done and last.end_reason == "max_steps" and not last.success


def test_heat_cool_clean_side_effects(twin, make_task, run):
    twin.reset(make_task("pick_heat_then_place_in_recep", parent="Desk"))
    run(twin, "find a Apple", "pick up the Apple", "find a Microwave", "open the Microwave", "put down the object in hand")
    assert run(twin, "close the Microwave").progress == 0.0
    heated = run(twin, "turn on the Microwave")
    assert heated.feedback == OK and heated.progress == pytest.approx(1 / 3)
    run(twin, "turn off the Microwave", "open the Microwave", "pick up the Apple", "find a Desk")
    assert run(twin, "put down the object in hand").success

    twin.reset(make_task("pick_cool_then_place_in_recep", parent="CounterTop", obj="Potato"))
    run(twin, "find a Potato", "pick up the Potato", "find a Fridge", "open the Fridge", "put down the object in hand")
    assert run(twin, "close the Fridge").progress == pytest.approx(1 / 3)

    twin.reset(make_task("pick_clean_then_place_in_recep", parent="CounterTop", obj="Potato"))
    run(twin, "find a Potato", "pick up the Potato", "find a Sink", "put down the object in hand")
    potato = twin._scene.index_of["Potato|-03.10|+00.80|+02.90"]
    assert twin._scene.index_of["Sink|+03.00|+00.90|+03.00|SinkBasin"] in twin._world.holders(potato)
    cleaned = run(twin, "turn on the Faucet")
    assert cleaned.feedback == OK and cleaned.progress == pytest.approx(1 / 3)


def test_slicing_needs_a_knife_and_makes_pieces(twin, make_task, run):
    twin.reset(make_task(parent="Fridge", sliced=True))
    run(twin, "find a Knife", "pick up the Knife", "find a Apple")
    r = run(twin, "slice the Apple")
    assert r.feedback == OK and r.progress == 0.5  # a sliced piece exists: 1 of 2 conditions
    run(twin, "find a Fridge", "open the Fridge", "put down the object in hand", "find a Apple", "pick up the Apple")
    held = twin._scene.objects[twin._world.holding]
    assert held.type == "AppleSliced"
    assert run(twin, "find a Fridge", "put down the object in hand").success


def test_drop_lands_on_the_receptacle_in_front(twin, make_task, run):
    twin.reset(make_task())
    run(twin, "find a Apple", "pick up the Apple")
    r = run(twin, "put down the object in hand")  # no current receptacle after pick up: a drop
    apple = twin._scene.index_of["Apple|+00.10|+01.00|+00.10"]
    assert r.feedback == OK and twin._scene.objects[twin._world.parent[apple]].type == "CounterTop"


def test_object_names_match_by_substring(twin, make_task, run):
    # ALFRED matches targets inside objectIds: a 'Pot' target is satisfied by a Potato.
    twin.reset(make_task(obj="Pot", parent="Fridge"))
    run(twin, "find a Fridge", "open the Fridge", "find a Potato", "pick up the Potato", "find a Fridge")
    assert run(twin, "put down the object in hand").success


def test_look_at_needs_lamp_on_and_visible(twin, make_task, run):
    twin.reset(make_task("look_at_obj_in_light", obj="Book", parent="", toggle="DeskLamp"))
    run(twin, "find a Book", "pick up the Book")
    assert run(twin, "find a DeskLamp").progress == 0.5
    assert run(twin, "turn on the DeskLamp").success


def test_instance_names_and_extra_actions(twin, make_task):
    twin.reset(make_task())
    assert len(twin.actions) > 162
    extra = twin.actions[162:]
    assert extra == ["find a Cabinet_2", "open the Cabinet_2", "close the Cabinet_2", "find a Apple_2"]
    with pytest.raises(UnknownActionError):
        twin.action_id("find a Unicorn")
    with pytest.raises(UnknownActionError):
        twin.step(len(twin.actions))


def test_exact_instance_navigation(twin, make_task, run):
    twin.reset(make_task())
    run(twin, "find a Apple_2")
    assert twin._world.location == "Apple_2"
    r = run(twin, "pick up the Apple")
    assert twin._scene.objects[twin._world.holding].object_id == "Apple|-02.90|+00.80|+03.10" and r.feedback == OK


def test_observation_is_lazy_and_bound_to_its_step(twin, make_task, run):
    twin.reset(make_task())
    first = run(twin, "find a Fridge").observation
    second = run(twin, "open the Fridge").observation
    assert "Fridge (closed)" in first.text
    assert "Fridge (open; contains: Mug)" in second.text
    assert first.state["location"] == "Fridge" and second.state["holding"] is None
