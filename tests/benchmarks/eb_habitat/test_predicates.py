"""Goal expressions: habitat-lab's grounding of AND/NAND/OR/NOR with EXISTS/FORALL, nested, and predicates."""

from __future__ import annotations

import pytest

from benchmarks.eb_habitat.predicates import (
    PredicateError,
    compile_node,
    ground_expr,
    ground_pred,
    parse_call,
)
from benchmarks.eb_habitat.world import STATIC_INDEX, Entities, World


@pytest.fixture
def ents(episode) -> Entities:
    return Entities.from_episode(episode)


@pytest.fixture
def world(ents) -> World:
    return World(list(ents.start), [False] * len(STATIC_INDEX))


def holds(expr, ents, world) -> bool:
    return compile_node(ground_expr(expr, ents))(world)


def on(name: str, recep: str, ents: Entities, world: World) -> None:
    world.recep[ents.index[name]] = STATIC_INDEX[recep]


def exists(cat: str, *subs, op: str = "AND", names=("X",)):
    return {
        "expr_type": op,
        "quantifier": "EXISTS",
        "inputs": [{"name": n, "expr_type": cat} for n in names],
        "sub_exprs": list(subs),
    }


def test_parse_call():
    assert parse_call("on_top(X, recep_a)") == ("on_top", ["X", "recep_a"])
    assert parse_call(" not_holding() ") == ("not_holding", [])
    with pytest.raises(PredicateError):
        parse_call("on_top X")


def test_exists_and_forall(ents, world, names):
    some = exists("apple", f"on_top(X, {names.SOFA})", "not_holding()")
    every = {**some, "quantifier": "FORALL"}
    assert not holds(some, ents, world) and not holds(every, ents, world)
    on(names.APPLE_T1, names.SOFA, ents, world)
    assert holds(some, ents, world) and not holds(every, ents, world)
    on(names.APPLE_SINK, names.SOFA, ents, world)
    assert holds(every, ents, world)
    world.held = ents.index[names.CUP]
    assert not holds(some, ents, world)  # not_holding sits inside every assignment


def test_nand_exists_follows_habitat_expansion(ents, world, names):
    # NAND + EXISTS X: [on_top(X, sink)] = OR over apples of NOT on_top(X, sink).
    off_sink = {
        "expr_type": "AND",
        "sub_exprs": ["not_holding()", exists("apple", f"on_top(X, {names.SINK})", op="NAND")],
    }
    assert holds(off_sink, ents, world)  # the table apple is not on the sink
    on(names.APPLE_T1, names.SINK, ents, world)
    assert not holds(off_sink, ents, world)  # every apple is on the sink
    nor = {"expr_type": "NOR", "sub_exprs": [f"on_top({names.APPLE_T1},{names.SINK})", "not_holding()"]}
    world.held = ents.index[names.CUP]
    assert not holds(nor, ents, world)
    world.recep[ents.index[names.APPLE_T1]] = STATIC_INDEX[names.SOFA]
    assert holds(nor, ents, world)


def test_two_variables_may_name_the_same_object(ents, world, names):
    both = exists("apple", f"on_top(X, {names.SOFA})", f"on_top(Y, {names.SOFA})", names=("X", "Y"))
    on(names.APPLE_SINK, names.SOFA, ents, world)
    assert holds(both, ents, world)


def test_nested_quantifier_sees_the_outer_variable(ents, world, names):
    # Some mug shares a receptacle with some apple: expressed as an inner EXISTS over apples using X.
    inner = {
        "expr_type": "OR",
        "quantifier": "EXISTS",
        "inputs": [{"name": "Y", "expr_type": "apple"}],
        "sub_exprs": [
            {"expr_type": "AND", "sub_exprs": [f"on_top(X, {names.SOFA})", f"on_top(Y, {names.SOFA})"]}
        ],
    }
    expr = exists("mug", inner)
    assert not holds(expr, ents, world)
    on(names.CUP, names.SOFA, ents, world)
    assert not holds(expr, ents, world)
    on(names.APPLE_T1, names.SOFA, ents, world)
    assert holds(expr, ents, world)


def test_missing_category_expands_to_nothing(ents, world, names):
    assert not holds(exists("banana", f"on_top(X, {names.SOFA})"), ents, world)
    assert holds({**exists("banana", f"on_top(X, {names.SOFA})"), "quantifier": "FORALL"}, ents, world)


def test_held_object_counts_on_top_of_the_robots_receptacle_only(ents, world, names):
    pred = ground_pred(f"on_top({names.APPLE_T1},{names.SOFA})", ents)
    apple = ents.index[names.APPLE_T1]
    world.held, world.recep[apple] = apple, -1
    world.place = STATIC_INDEX[names.TABLE_1]
    assert not pred.test(world)
    world.place = STATIC_INDEX[names.SOFA]
    assert pred.test(world)


def test_robot_at_and_doors(ents, world, names):
    at_sink = ground_pred(f"robot_at({names.SINK})", ents)
    near_cup = ground_pred(f"robot_at_obj({names.CUP})", ents)
    assert not at_sink.test(world) and not near_cup.test(world)  # nowhere yet
    world.place = STATIC_INDEX[names.COUNTER_LEFT]
    assert at_sink.test(world) and near_cup.test(world)
    closed = ground_pred("closed_fridge(fridge_push_point)", ents)
    assert closed.test(world)
    world.door_open[STATIC_INDEX["fridge_push_point"]] = True
    assert ground_pred("opened_fridge(fridge_push_point)", ents).test(world) and not closed.test(world)
    assert ground_pred(f"in({names.KNIFE},fridge_push_point)", ents).test(world)


@pytest.mark.parametrize(
    "text",
    [
        "teleport(X)",
        "on_top(nonexistent_:0000,receptacle_aabb_sink_kitchen_counter)",
        "holding()",
        "opened_fridge(cab_push_point_7)",
        "on_top(receptacle_aabb_sink_kitchen_counter,receptacle_aabb_sink_kitchen_counter)",
    ],
)
def test_bad_predicates_are_rejected(ents, text):
    with pytest.raises(PredicateError):
        ground_pred(text, ents)


def test_bad_expressions_are_rejected(ents):
    with pytest.raises(PredicateError):
        ground_expr({"expr_type": "XOR", "sub_exprs": []}, ents)
    with pytest.raises(PredicateError):
        ground_expr({"expr_type": "AND", "quantifier": "SOME", "inputs": [], "sub_exprs": []}, ents)
