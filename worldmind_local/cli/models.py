"""`worldmind models list` and `worldmind models check SPEC [--n N]`.

`list` prints every model spec (built-in `models/specs/*.yaml` plus `$WORLDMIND_MODEL_SPECS`) with
where its weights come from and whether they are on this machine. `check` loads one, sends N
structured planner-style requests in one batch plus one alone, and prints exactly one JSON line:
{"ok", "backend", "model", "json_valid_rate", "tokens_per_s_batch1", "tokens_per_s_batched", "load_s"}
(and "error" when it failed). The exit code is 0 only when ok.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

__all__ = ["register"]


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser("models", help="list model specs; check that a model loads and answers")
    sub = parser.add_subparsers(dest="models_command", metavar="ACTION")
    parser.set_defaults(func=lambda args: _no_action(parser))

    list_parser = sub.add_parser("list", help="table of model specs (address, model id, roles, weights, available)")
    list_parser.add_argument("--json", action="store_true", help="one JSON object per spec instead of a table")
    list_parser.set_defaults(func=_list)

    check = sub.add_parser("check", help="load SPEC, run N structured requests in one batch, print one JSON line")
    check.add_argument("spec", metavar="SPEC", help="model spec address, e.g. hf:smollm2-135m-instruct")
    check.add_argument("--n", type=int, default=8, help="requests in the batched run (default 8)")
    check.add_argument("--max-tokens", type=int, default=192, help="max_tokens per request (default 192)")
    check.add_argument(
        "--option", action="append", default=[], metavar="KEY=VALUE",
        help="backend option (VALUE read as JSON when it parses), e.g. --option device=cpu; repeatable",
    )
    check.set_defaults(func=_check)


def _no_action(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def _rows() -> list[dict[str, str]]:
    from models.specs import list_specs
    from models.weights import is_available, weights_description

    return [
        {
            "address": spec.address,
            "model_id": spec.model_id,
            "roles": ",".join(spec.roles) or "-",
            "weights": weights_description(spec),
            "available": "yes" if is_available(spec) else "no",
        }
        for spec in list_specs()
    ]


def _list(args: argparse.Namespace) -> int:
    rows = _rows()
    if args.json:
        for row in rows:
            print(json.dumps(row))
        return 0
    columns = ["address", "model_id", "roles", "weights", "available"]
    widths = {c: max(len(c), *(len(r[c]) for r in rows)) for c in columns}
    print("  ".join(c.upper().ljust(widths[c]) for c in columns).rstrip())
    for row in rows:
        print("  ".join(row[c].ljust(widths[c]) for c in columns).rstrip())
    return 0


def _parse_options(pairs: list[str]) -> dict[str, Any]:
    options: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ValueError(f"--option {pair!r}: expected KEY=VALUE")
        try:
            options[key] = json.loads(value)
        except ValueError:
            options[key] = value
    return options


def _check(args: argparse.Namespace) -> int:
    from models.check import check_spec

    if args.n < 1 or args.max_tokens < 1:
        raise ValueError("--n and --max-tokens must be at least 1")
    report = check_spec(args.spec, n=args.n, max_tokens=args.max_tokens, **_parse_options(args.option))
    print(json.dumps(report), flush=True)
    return 0 if report["ok"] else 1
