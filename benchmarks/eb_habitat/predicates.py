"""Goal expressions and subgoals: parsing, grounding, and fast evaluation against a ``World``.

An episode's `goal_preds` is a nested expression: `expr_type` AND/NAND/OR/NOR over `sub_exprs`
(predicate strings or further expressions), optionally quantified (`quantifier` EXISTS/FORALL over
`inputs`, each a variable name and a category). Grounding follows habitat-lab's expansion exactly: a
quantified expression becomes OR (EXISTS) or AND (FORALL) over every assignment of its variables
(the cartesian product, so two variables of one category may name the same object), and each
assignment keeps the expression's own type. So `NAND` + `EXISTS X` means "some X makes the NAND
true", i.e. some X for which not all sub-expressions hold.

Grounding happens once per reset; a grounded node compiles to a closure over ``World`` so the goal
check in each step is a handful of int comparisons.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from .scene import CAB_MARKERS, FRIDGE_MARKER, MARKER_RECEPTACLE, MARKERS, RECEPTACLES, STATIC_ENTITIES
from .world import HOME_IDX, NOWHERE, STATIC_INDEX, Entities, World

__all__ = [
    "PredicateError",
    "Pred",
    "Expr",
    "Node",
    "parse_call",
    "ground_pred",
    "ground_expr",
    "compile_node",
]

Test = Callable[[World], bool]
Arg = tuple[str, int]  # ("obj", object index) | ("static", static index) | ("robot", 0)
_CALL = re.compile(r"^\s*([A-Za-z_]+)\s*\((.*)\)\s*$")
_OPS = ("AND", "NAND", "OR", "NOR")


class PredicateError(ValueError):
    """A predicate or expression that does not fit the EB-Habitat domain."""


@dataclass(frozen=True)
class Pred:
    """A ground predicate: its name, resolved arguments, entity names, and compiled test."""

    name: str
    args: tuple[Arg, ...]
    names: tuple[str, ...]
    test: Test = field(repr=False, compare=False)

    def __str__(self) -> str:
        return f"{self.name}({','.join(self.names)})"


@dataclass(frozen=True)
class Expr:
    """A ground logical node: `op` is and / or / nand / nor."""

    op: str
    children: tuple[Node, ...]


Node = Pred | Expr


def parse_call(text: str) -> tuple[str, list[str]]:
    """`"on_top(X, recep)"` -> `("on_top", ["X", "recep"])`."""
    match = _CALL.match(text) if isinstance(text, str) else None
    if match is None:
        raise PredicateError(f"not a predicate call: {text!r}")
    inner = match.group(2).strip()
    return match.group(1), [a.strip() for a in inner.split(",")] if inner else []


def _resolve(token: str, ents: Entities, bindings: Mapping[str, Arg]) -> tuple[Arg, str]:
    if token in bindings:
        arg = bindings[token]
    elif token in ents.index:
        arg = ("obj", ents.index[token])
    elif token in STATIC_INDEX:
        arg = ("static", STATIC_INDEX[token])
    elif token.startswith("robot_"):
        arg = ("robot", 0)
    else:
        raise PredicateError(f"unknown entity {token!r}")
    kind, idx = arg
    name = ents.names[idx] if kind == "obj" else (STATIC_ENTITIES[idx] if kind == "static" else token)
    return arg, name


_RECEPTACLE_IDX = frozenset(STATIC_INDEX[r] for r in RECEPTACLES)
_CAB_IDX = frozenset(STATIC_INDEX[m] for m in CAB_MARKERS)
_FRIDGE_IDX = frozenset({STATIC_INDEX[FRIDGE_MARKER]})


def _kinds(name: str, args: tuple[Arg, ...], *expected: frozenset[int] | str) -> None:
    if len(args) != len(expected):
        raise PredicateError(f"{name} takes {len(expected)} argument(s), got {len(args)}")
    for (kind, idx), want in zip(args, expected, strict=True):
        ok = kind == want if isinstance(want, str) else (kind == "static" and idx in want)
        if not ok:
            raise PredicateError(f"{name}: argument of the wrong kind")


def _test(name: str, args: tuple[Arg, ...]) -> Test:
    if name in ("on_top", "at"):
        _kinds(name, args, "obj", _RECEPTACLE_IDX)
        o, r = args[0][1], args[1][1]
        if name == "at":
            return lambda w: w.recep[o] == r
        return lambda w: w.recep[o] == r or (w.held == o and r in HOME_IDX[w.place])
    if name == "in":
        _kinds(name, args, "obj", frozenset(STATIC_INDEX[m] for m in MARKERS))
        o, marker = args[0][1], STATIC_ENTITIES[args[1][1]]
        r = STATIC_INDEX[MARKER_RECEPTACLE[marker]] if marker in MARKER_RECEPTACLE else -2
        return lambda w: w.recep[o] == r
    if name == "holding":
        _kinds(name, args, "obj")
        o = args[0][1]
        return lambda w: w.held == o
    if name == "not_holding":
        _kinds(name, args)
        return lambda w: w.held == NOWHERE
    if name in ("robot_at", "robot_at_obj", "robot_at_closest"):
        if len(args) != 1 or args[0][0] == "robot" or (name == "robot_at_obj" and args[0][0] != "obj"):
            raise PredicateError(f"{name} takes one object or receptacle")
        kind, i = args[0]
        if kind == "static":
            return lambda w: i in w.reach[w.place]
        return lambda w: w.near(i)
    if name in ("opened_fridge", "closed_fridge", "opened_cab", "closed_cab"):
        _kinds(name, args, _FRIDGE_IDX if name.endswith("fridge") else _CAB_IDX)
        m = args[0][1]
        if name.startswith("opened"):
            return lambda w: w.door_open[m]
        return lambda w: not w.door_open[m]
    raise PredicateError(f"unknown predicate {name!r}")


def ground_pred(text: str, ents: Entities, bindings: Mapping[str, Arg] | None = None) -> Pred:
    name, tokens = parse_call(text)
    resolved = [_resolve(t, ents, bindings or {}) for t in tokens]
    args = tuple(a for a, _ in resolved)
    return Pred(name, args, tuple(n for _, n in resolved), _test(name, args))


def _domain(type_name: str, ents: Entities) -> list[Arg]:
    if type_name in ents.by_category:
        return [("obj", i) for i in ents.by_category[type_name]]
    if type_name == "movable_entity_type":
        return [("obj", i) for i in range(len(ents.names))]
    fixed = {"cab_type": CAB_MARKERS, "fridge_type": (FRIDGE_MARKER,), "place_receptacle": RECEPTACLES}
    if type_name in fixed:
        return [("static", STATIC_INDEX[n]) for n in fixed[type_name]]
    return []  # a category with no instance in this episode: habitat expands it to nothing


def ground_expr(expr: Any, ents: Entities, bindings: Mapping[str, Arg] | None = None) -> Node:
    """Ground a goal expression (dict) or predicate (str) for one episode."""
    bindings = dict(bindings or {})
    if isinstance(expr, str):
        return ground_pred(expr, ents, bindings)
    if not isinstance(expr, Mapping) or expr.get("expr_type") not in _OPS:
        raise PredicateError(f"expected a predicate string or an expression with expr_type in {_OPS}")
    subs = expr.get("sub_exprs")
    if not isinstance(subs, list):
        raise PredicateError("sub_exprs must be a list")
    op, quantifier = expr["expr_type"].lower(), expr.get("quantifier")

    def build(b: Mapping[str, Arg]) -> Expr:
        return Expr(op, tuple(ground_expr(s, ents, b) for s in subs))

    if quantifier is None:
        return build(bindings)
    if quantifier not in ("EXISTS", "FORALL"):
        raise PredicateError(f"unknown quantifier {quantifier!r}")
    inputs = expr.get("inputs") or []
    try:
        names = [str(i["name"]) for i in inputs]
        domains = [_domain(str(i["expr_type"]), ents) for i in inputs]
    except (TypeError, KeyError) as exc:
        raise PredicateError("inputs must be a list of {name, expr_type}") from exc
    cases = tuple(
        build({**bindings, **dict(zip(names, combo, strict=True))}) for combo in itertools.product(*domains)
    )
    return Expr("and" if quantifier == "FORALL" else "or", cases)


def compile_node(node: Node) -> Test:
    """A closure that evaluates the node against a World (short-circuits; same value as habitat's reduce)."""
    if isinstance(node, Pred):
        return node.test
    tests = tuple(compile_node(c) for c in node.children)
    conj = node.op in ("and", "nand")
    negate = node.op in ("nand", "nor")

    def holds(w: World) -> bool:
        value = conj
        for t in tests:
            if t(w) != conj:
                value = not conj
                break
        return value != negate

    return holds
