"""`worldmind` command line. Each subcommand lives in its own module of this package.

A subcommand module defines `register(subparsers)`, which adds its parser and sets
`func=<callable(args) -> int>`. Subcommand modules import nothing heavy at module level.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

__all__ = ["main", "build_parser"]

# Order = order in --help.
SUBCOMMAND_MODULES = (
    "worldmind_local.cli.run",
    "worldmind_local.cli.replay",
    "worldmind_local.cli.tasks",
    "worldmind_local.cli.models",
    "worldmind_local.cli.methods",
    "worldmind_local.cli.show",
    "worldmind_local.cli.memory",
    "worldmind_local.cli.transfer",
    "worldmind_local.cli.report",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="worldmind",
        description="WorldMind-Local: local-model batch evaluation of WorldMind on EmbodiedBench.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name == name:  # subcommand not built yet
                continue
            raise
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted; re-run the same command to resume", file=sys.stderr)
        return 130
    except (FileNotFoundError, ValueError, KeyError) as exc:
        # User-facing input problems: one clear line, no traceback.
        msg = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc
        print(f"worldmind {args.command}: error: {msg}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
