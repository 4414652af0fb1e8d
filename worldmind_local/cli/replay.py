"""`worldmind replay`: run fixed plans (or each task's expert plan) and report SR/GC per subset."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any, TextIO

__all__ = ["register", "add_suite_arguments", "suite_from_args"]


def add_suite_arguments(p: argparse.ArgumentParser) -> None:
    """--benchmark plus the suite selection shared by `replay` and `tasks`."""
    p.add_argument("--benchmark", required=True, help="eb_alfred, eb_habitat or eb_navigation")
    p.add_argument("--data-dir", help="EmbodiedBench data pack (default: $WORLDMIND_DATA, then ~/.cache/worldmind/embodiedbench)")
    p.add_argument("--suite", choices=("embodiedbench", "generated"), help="default: the data pack if present, else generated")
    p.add_argument("--seed", type=int, default=0, help="seed of a generated suite (default 0)")
    p.add_argument("--per-subset", type=int, default=50, help="tasks per subset of a generated suite (default 50)")


def suite_from_args(args: argparse.Namespace) -> Any:
    from worldmind_local.data import load_suite

    if args.per_subset < 1:
        raise ValueError("--per-subset must be at least 1")
    return load_suite(args.benchmark, data_dir=args.data_dir, suite=args.suite, seed=args.seed, n_per_subset=args.per_subset)


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "replay",
        help="replay action plans on a benchmark env and report success/progress",
        description="Replay plans ({subset, index, actions} per line) or each task's expert plan (--expert).",
    )
    add_suite_arguments(p)
    p.add_argument("--env", default="twin", help="twin (default) or embodiedbench")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--plans", help="JSONL plan file, or - for stdin")
    src.add_argument("--expert", action="store_true", help="replay every task's own expert plan")
    p.add_argument("--subsets", help="comma-separated subsets for --expert (default: all)")
    p.add_argument("--out", default="-", help="JSONL results file (default: stdout)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


@contextlib.contextmanager
def _output(path: str) -> Iterator[TextIO]:
    if path == "-":
        yield sys.stdout
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f:
        yield f


def _plan_lines(args: argparse.Namespace, replayer: Any, subsets: list[str]) -> list[str]:
    from worldmind_local.replay import expert_lines

    if args.expert:
        return list(expert_lines(replayer, subsets))
    if args.plans == "-":
        raw = getattr(sys.stdin, "buffer", None)  # a text-only stdin (a test's StringIO) is read as is
        return _decode_lines(raw.read()) if raw is not None else sys.stdin.read().splitlines()
    path = Path(args.plans)
    if not path.is_file():
        raise FileNotFoundError(f"plan file {path} not found")
    return _decode_lines(path.read_bytes())


def _decode_lines(data: bytes) -> list[str]:
    """Lines as text; bytes that are not UTF-8 survive as surrogate escapes, so that line (and only
    it) becomes an error line naming its number instead of aborting the whole replay."""
    return data.decode("utf-8", errors="surrogateescape").splitlines()


def run(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except ImportError as exc:  # an optional env (e.g. --env embodiedbench) is not installed
        print(f"worldmind replay: error: {exc}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from worldmind_local.data import adapter
    from worldmind_local.replay import Replayer, replay_lines

    suite = suite_from_args(args)
    known = adapter(args.benchmark).subsets
    subsets = [s.strip() for s in args.subsets.split(",")] if args.subsets else list(known)
    unknown = [s for s in subsets if s not in known]
    if unknown:
        raise ValueError(f"unknown subset(s) {', '.join(unknown)} for {args.benchmark}; known: {', '.join(known)}")
    replayer = Replayer(suite, env_kind=args.env)
    try:
        lines = _plan_lines(args, replayer, subsets)
        report = sys.stderr if args.out == "-" else sys.stdout
        with _output(args.out) as out, tqdm(total=sum(1 for x in lines if x.strip()), disable=args.no_progress,
                                            file=sys.stderr, unit="ep", desc="replay") as bar:
            replay_lines(replayer, lines, out, tick=lambda: bar.update(1))
    finally:
        replayer.close()
    print(f"{suite.describe()} on the {args.env} env", file=report)
    print(f"{'subset':<22}{'episodes':>9}{'SR %':>8}{'GC %':>8}{'errors':>8}", file=report)
    for name, score in replayer.scores.items():
        print(f"{name:<22}{score.episodes:>9}{100 * score.sr:>8.1f}{100 * score.gc:>8.1f}{score.errors:>8}", file=report)
    if replayer.skipped:
        print(f"{replayer.skipped} line(s) named no episode and were skipped (see their \"error\")", file=report)
    return 0
