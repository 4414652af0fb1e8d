"""`worldmind methods list`: every registered method with its memory scope and one-line description."""

from __future__ import annotations

import argparse
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser("methods", help="list the methods (WorldMind, its ablations, baselines)")
    msub = p.add_subparsers(dest="methods_command", metavar="ACTION")
    lp = msub.add_parser("list", help="each method: memory scope, description, options")
    lp.add_argument("--options", action="store_true", help="also list each method's options and defaults")
    lp.set_defaults(func=main)
    p.set_defaults(func=main, options=False)


def main(args: argparse.Namespace) -> int:
    from worldmind_local.registry import METHODS

    rows = []
    for name in METHODS.names():
        cls = METHODS.get(name)
        rows.append((name, cls.memory_scope, cls.description))
    width = max(len(r[0]) for r in rows)
    for name, scope, description in rows:
        print(f"{name:<{width}}  {scope:<8}  {description}")
        if args.options:
            cfg = METHODS.get(name).config_class
            fixed = getattr(METHODS.get(name), "fixed", {})
            for key, info in cfg.model_fields.items():
                value = fixed.get(key, info.default)
                note = " (fixed)" if key in fixed else ""
                print(f"{'':<{width}}    {key} = {value}{note}")
    return 0
