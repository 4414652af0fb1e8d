#!/usr/bin/env python
"""Fuzz every parser of model output with generated malformed answers (issue 18, point 5).

For each role (planner, judge, reflector, distiller, summarizer) and for `worldmind replay --plans`
lines, feeds `--n` generated outputs (default 10,000 per role) through the parser the agent uses and
prints, per role: the count, the exceptions that escaped (target 0), the slowest parse in ms (target
under 50 ms) and a histogram of how each output was classified (parsed, or which counted error).

Classes of generated output: valid answers (plain, fenced, with prose), deep nesting (100 to 100,000
brackets), huge integers (101 to 10,000 digits), NaN / Infinity / 1e999, truncation at a random
point, random bytes decoded as text, runs of brackets (8 kB and 100 kB), valid JSON with wrongly typed
fields, exotic unicode (lone surrogates, NUL, RTL marks, emoji), code fences (closed, open, nested)
and long strings of escapes.

    python scripts/fuzz_outputs.py [--n 10000] [--seed 0] [--roles planner,judge]

Exit status 1 when any exception escaped a parser.
"""

from __future__ import annotations

import argparse
import copy
import json
import random
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ROLES = ("planner", "judge", "reflector", "distiller", "summarizer", "replay")

VALID: dict[str, Callable[[random.Random], dict[str, Any]]] = {
    "planner": lambda r: {
        "language_plan": "find the apple, then pick it up",
        "executable_plan": [
            {"action_id": r.randrange(0, 40), "action_name": f"find a {w}", "predicted_state": f"I see the {w}."}
            for w in r.sample(["apple", "fridge", "mug", "sink", "knife"], r.randrange(0, 4))
        ],
    },
    "judge": lambda r: {"verdict": r.choice(["match", "mismatch"]), "reason": "the fridge is closed"},
    "reflector": lambda r: {"rules": [f"rule {i}: open the fridge before taking from it" for i in range(r.randrange(1, 4))]},
    "distiller": lambda r: {"workflow": "1. find [TARGET_OBJECT] 2. pick it up 3. put it in [RECEPTACLE]"},
    "summarizer": lambda r: {"state_before": "holding nothing", "state_after": "holding the apple"},
    "replay": lambda r: {"subset": "base", "index": r.randrange(0, 3), "actions": ["find a Apple", "pick up the Apple"]},
}

_ODD_CHARS = ["\x00", "\u202e", "\u200b", "\ud800", "\udfff", "\U0001f600", "e\u0301", "\ufeff", "\\", '"', "\n"]


def _dump(obj: Any, r: random.Random) -> str:
    return json.dumps(obj, ensure_ascii=r.random() < 0.5, indent=r.choice([None, 2]))


def _bracket_pool(r: random.Random) -> list[str]:
    """Big bracket runs made once (drawing 100 kB char by char per sample would dominate the run)."""
    pool = []
    for size in (8_000, 100_000):
        pool += ["{" * size, "[" * size, "}" * size, "{[" * (size // 2), "[{" * (size // 2),
                 "".join(r.choices("{}[]", k=size)), "".join(r.choices('{}[]":,', k=size)),
                 '{"a":' * (size // 5), "{}" * (size // 2), "{x}" * (size // 3)]
    return pool


@dataclass
class Generator:
    """Malformed outputs of one role; each draw names its class so the report can say what broke."""

    role: str
    rng: random.Random
    pool: list[str] = field(default_factory=list)

    def valid_text(self) -> str:
        return _dump(VALID[self.role](self.rng), self.rng)

    def draw(self) -> tuple[str, str]:
        name, make = self.rng.choice(self.classes())
        return name, make()

    def classes(self) -> list[tuple[str, Callable[[], str]]]:
        return [
            ("valid", self.valid_text),
            ("fenced", self.fenced),
            ("prose", self.prose),
            ("deep_nesting", self.deep_nesting),
            ("huge_int", self.huge_int),
            ("non_finite", self.non_finite),
            ("truncated", self.truncated),
            ("random_bytes", self.random_bytes),
            ("bracket_run", self.bracket_run),
            ("wrong_types", self.wrong_types),
            ("unicode", self.unicode),
            ("long_escapes", self.long_escapes),
        ]

    def fenced(self) -> str:
        body = self.valid_text()
        return self.rng.choice([f"```json\n{body}\n```", f"```\n{body}", f"```JSON{body}``````", f"``{body}`"])

    def prose(self) -> str:
        body = self.valid_text()
        return self.rng.choice([f"Sure! {{not json}} here: {body} and {{\"x\": 1}}", f"I think \"{{\" {body}",
                                f"{body[: len(body) // 2]} ... let me restart: {body}", f"no json at all {self.rng.random()}"])

    def deep_nesting(self) -> str:
        k = self.rng.choice([65, 100, 1_000, 5_000, 100_000])
        opener = self.rng.choice(["{", "[", '{"a":', '{"a":['])
        closer = {"{": "}", "[": "]", '{"a":': "}", '{"a":[': "]}"}[opener]
        inner = opener * k + "1" + closer * k
        return self.rng.choice([inner, self.valid_text()[:-1] + f', "deep": {inner}}}', f"{inner} {self.valid_text()}"])

    def huge_int(self) -> str:
        digits = "9" * self.rng.choice([101, 4_301, 10_000])
        obj = VALID[self.role](self.rng)
        key = self.rng.choice(list(obj))
        return _dump(obj, self.rng).replace(json.dumps(key) + ":", json.dumps(key) + ": " + digits + ", \"_\":", 1)

    def non_finite(self) -> str:
        obj = VALID[self.role](self.rng)
        key = self.rng.choice(list(obj))
        lit = self.rng.choice(["NaN", "Infinity", "-Infinity", "1e999", "-1e999"])
        return json.dumps(obj).replace(json.dumps(key) + ":", json.dumps(key) + ": " + lit + ", \"_\":", 1)

    def truncated(self) -> str:
        text = self.valid_text()
        return text[: self.rng.randrange(0, len(text) + 1)]

    def random_bytes(self) -> str:
        data = self.rng.randbytes(self.rng.choice([1, 16, 512, 8_192]))
        codec = self.rng.choice(["utf-8", "latin-1", "utf-16"])
        errors = "replace" if codec == "utf-16" else self.rng.choice(["replace", "surrogateescape", "ignore"])
        return data.decode(codec, errors=errors)

    def bracket_run(self) -> str:
        run = self.rng.choice(self.pool)
        return self.rng.choice([run, run + self.valid_text(), self.valid_text()[:-1] + run])

    def wrong_types(self) -> str:
        obj = VALID[self.role](self.rng)
        odd = [None, True, 0, -1, 2**63, 1.5, "", "x", [], {}, [1, "a"], {"k": []}]
        for key in self.rng.sample(list(obj), self.rng.randrange(1, len(obj) + 1)):
            obj[key] = copy.deepcopy(self.rng.choice(odd))
        if self.role == "planner" and isinstance(obj.get("executable_plan"), list):
            obj["executable_plan"].append(copy.deepcopy(self.rng.choice(odd)))
        return json.dumps(obj)

    def unicode(self) -> str:
        text = self.valid_text()
        for _ in range(self.rng.randrange(1, 8)):
            at = self.rng.randrange(0, len(text) + 1)
            text = text[:at] + self.rng.choice(_ODD_CHARS) + text[at:]
        return text

    def long_escapes(self) -> str:
        body = self.rng.choice(['\\"', "\\\\", "\\u0000", "\\ud800", "x"]) * self.rng.choice([1_000, 50_000])
        return self.valid_text()[:-1] + f', "long": "{body}"}}'


def _classify_planner(text: str) -> str:
    from worldmind_local.agent.plan import PlanParseError, parse_plan

    try:
        plan = parse_plan(text)
    except PlanParseError as exc:
        return "parse_error: " + _error_kind(str(exc))
    return "empty_plan" if plan.empty else "plan"


def _error_kind(message: str) -> str:
    """Group error messages by their fixed wording (numbers and quoted values removed)."""
    words = [w for w in message.split()
             if not w.strip(".,:()").isdigit() and not any(c in w for c in "'\"[")]
    return " ".join(words[:6])


def _classify_judge(text: str) -> str:
    from worldmind_local.agent.judge import parse_verdict

    verdict = parse_verdict(text)
    return "unparseable (match)" if verdict.unparseable else verdict.verdict


def _classify_reflector(text: str) -> str:
    from worldmind_local.agent.reflector import parse_rules

    rules, unparseable = parse_rules(text, 3)
    return "unparseable" if unparseable else f"{len(rules)} rule(s)"


def _classify_distiller(text: str) -> str:
    from worldmind_local.agent.distiller import parse_workflow

    return "workflow" if parse_workflow(text) is not None else "unparseable"


def _classify_summarizer(text: str) -> str:
    from worldmind_local.agent.abstractor import parse_summary

    _before, _after, parsed = parse_summary(text, "env before", "env after")
    return "json" if parsed else "free text"


def _classify_replay(text: str) -> str:
    from worldmind_local.replay import PlanError, _parse

    try:
        _parse(text, 1)
    except PlanError as exc:
        return "error: " + _error_kind(str(exc).partition(": ")[2])
    return "plan line"


CLASSIFIERS: dict[str, Callable[[str], str]] = {
    "planner": _classify_planner, "judge": _classify_judge, "reflector": _classify_reflector,
    "distiller": _classify_distiller, "summarizer": _classify_summarizer, "replay": _classify_replay,
}


@dataclass
class RoleReport:
    role: str
    count: int = 0
    exceptions: list[str] = field(default_factory=list)
    slowest_ms: float = 0.0
    slowest_class: str = ""
    classes: Counter[str] = field(default_factory=Counter)
    outcomes: Counter[str] = field(default_factory=Counter)


def outputs(role: str, n: int, seed: int) -> Iterator[tuple[str, str]]:
    """`n` generated (class, text) pairs for `role`, deterministic per seed."""
    rng = random.Random(f"{seed}:{role}")
    gen = Generator(role, rng, _bracket_pool(random.Random(seed)))
    for _ in range(n):
        yield gen.draw()


def fuzz_role(role: str, n: int, seed: int) -> RoleReport:
    """Parse `n` outputs; any exception other than the parser's declared error is recorded."""
    classify = CLASSIFIERS[role]
    classify("")  # import the parser's modules before timing anything
    report = RoleReport(role)
    for cls, text in outputs(role, n, seed):
        t0 = time.perf_counter()
        try:
            outcome = classify(text)
        except Exception as exc:  # noqa: BLE001 - the point is to catch anything that escapes
            outcome = f"EXCEPTION {type(exc).__name__}"
            report.exceptions.append(f"{cls}: {type(exc).__name__}: {str(exc)[:120]}")
        ms = (time.perf_counter() - t0) * 1000
        if ms > report.slowest_ms:
            report.slowest_ms, report.slowest_class = ms, f"{cls}, {len(text)} chars"
        report.count += 1
        report.classes[cls] += 1
        report.outcomes[outcome] += 1
    return report


def print_report(report: RoleReport) -> None:
    print(f"{report.role}: {report.count} outputs, {len(report.exceptions)} exceptions, "
          f"slowest parse {report.slowest_ms:.2f} ms ({report.slowest_class})")
    for outcome, count in report.outcomes.most_common():
        print(f"    {count:>6}  {outcome}")
    for line in report.exceptions[:5]:
        print(f"    ! {line}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=10_000, help="outputs per role (default 10,000)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--roles", default=",".join(ROLES), help=f"comma-separated subset of {', '.join(ROLES)}")
    args = p.parse_args(argv)
    total_exceptions, slowest = 0, 0.0
    for role in [r.strip() for r in args.roles.split(",") if r.strip()]:
        if role not in CLASSIFIERS:
            p.error(f"unknown role {role!r}; known: {', '.join(ROLES)}")
        report = fuzz_role(role, args.n, args.seed)
        print_report(report)
        total_exceptions += len(report.exceptions)
        slowest = max(slowest, report.slowest_ms)
    print(f"total: {total_exceptions} exceptions (target 0), slowest parse {slowest:.2f} ms (target < 50 ms)")
    return 1 if total_exceptions else 0


if __name__ == "__main__":
    sys.exit(main())
