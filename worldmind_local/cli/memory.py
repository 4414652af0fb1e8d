"""`worldmind memory`: export, publish, show, count, filter, merge and diff repositories.

SRC anywhere below is what `--memory-from` takes: a run folder (one stream), a stream's `memory/`, an
export, a parquet file or folder, or `hub:OWNER/NAME[@REV]` from the local Hub cache. Outputs always go
to a new folder; inputs are never written.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from typing import Any

__all__ = ["register"]


def register(sub: Any) -> None:
    p = sub.add_parser("memory", help="export / push / show / stats / filter / merge / diff repositories",
                       description=__doc__)
    tools = p.add_subparsers(dest="memory_command", metavar="TOOL")

    e = tools.add_parser("export", help="write SRC as a Hub dataset repository folder (card + parquet)")
    e.add_argument("source", metavar="RUN_OR_MEMORY")
    e.add_argument("out", metavar="DIR", help="a new folder")
    e.add_argument("--license", default="cc-by-4.0", help="the card's license (default cc-by-4.0)")
    e.set_defaults(func=_guard(_export))

    u = tools.add_parser("push", help="publish an export (or SRC, exported first) to the Hub in one commit")
    u.add_argument("source", metavar="DIR_OR_RUN")
    u.add_argument("repo_id", metavar="REPO_ID", help="OWNER/NAME of the dataset repository")
    u.add_argument("--private", action="store_true", help="create the repository private")
    u.add_argument("--revision", default=None, help="branch to commit to (created if missing; default main)")
    u.set_defaults(func=_guard(_push))

    s = tools.add_parser("show", help="list entries with their provenance")
    s.add_argument("source", metavar="SRC")
    s.add_argument("--limit", type=int, default=50, help="entries to list (default 50; 0 = all)")
    s.add_argument("--partition", default=None, help="only this partition (process, goal, or a store's kind)")
    s.set_defaults(func=_guard(_show))

    t = tools.add_parser("stats", help="counts per partition, benchmark, source task and model")
    t.add_argument("source", metavar="SRC")
    t.add_argument("--json", action="store_true", help="print JSON")
    t.set_defaults(func=_guard(_stats))

    f = tools.add_parser("filter", help="write the entries that match into a new export folder")
    f.add_argument("source", metavar="SRC")
    f.add_argument("out", metavar="DIR", help="a new folder")
    f.add_argument("--partition", default=None, help="comma list of partitions (or kinds)")
    f.add_argument("--benchmark", default=None, help="comma list of benchmarks")
    f.add_argument("--model", default=None, help="comma list of model ids (planner_model or judge_model)")
    f.add_argument("--episodes", default=None, metavar="A:B", help="source episodes A <= episode < B")
    f.set_defaults(func=_guard(_filter))

    m = tools.add_parser("merge", help="merge repositories (0.95 near-duplicate filter) into a new export")
    m.add_argument("sources", metavar="SRC", nargs="+")
    m.add_argument("--out", required=True, metavar="DIR", help="a new folder")
    m.add_argument("--dedup-threshold", type=float, default=0.95, help="cosine of a near-duplicate (0.95)")
    m.set_defaults(func=_guard(_merge))

    d = tools.add_parser("diff", help="entries only in A, only in B, or changed; differing settings")
    d.add_argument("a", metavar="A")
    d.add_argument("b", metavar="B")
    d.add_argument("--limit", type=int, default=20, help="entries listed per kind of difference")
    d.set_defaults(func=_guard(_diff))
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1])


def _guard(handler: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
    """One line, no traceback, for anything a user's input or the network can cause."""
    from worldmind_local.memory.hub import PublishError

    def run(args: argparse.Namespace) -> int:
        try:
            return handler(args)
        except (ValueError, OSError, PublishError) as exc:
            print(f"worldmind memory {args.memory_command}: error: {exc}", file=sys.stderr)
            return 2

    return run


def _list(value: str | None) -> list[str] | None:
    items = [x.strip() for x in (value or "").split(",") if x.strip()]
    return items or None


def _export(args: argparse.Namespace) -> int:
    from worldmind_local.memory.hub import export

    out, source = export(args.source, args.out, license=args.license)
    print(f"exported {source.entries} entries ({', '.join(f'{k} {v}' for k, v in source.counts.items())}) "
          f"from {source.kind} {source.location}")
    print(f"  -> {out}  (README.md card + data/*.parquet; sha256 {source.sha256[:16]})")
    print(f"  datasets.load_dataset({str(out)!r}) reads it; `worldmind memory push {out} OWNER/NAME` publishes it")
    return 0


def _push(args: argparse.Namespace) -> int:
    from worldmind_local.memory.hub import push

    info = push(args.source, args.repo_id, private=args.private, revision=args.revision)
    print(f"published {args.repo_id} ({'private' if args.private else 'public'}) in one commit: "
          f"{getattr(info, 'oid', '')} {getattr(info, 'commit_url', '')}")
    return 0


def _show(args: argparse.Namespace) -> int:
    from worldmind_local.memory.sources import open_source
    from worldmind_local.memory.tools import show_lines

    source, repo = open_source(args.source)
    print("\n".join(show_lines(source, repo, limit=args.limit or None, partition=args.partition)))
    return 0


def _stats(args: argparse.Namespace) -> int:
    from worldmind_local.memory.sources import open_source
    from worldmind_local.memory.tools import stats, stats_lines

    source, repo = open_source(args.source)
    counts = stats(repo)
    if args.json:
        print(json.dumps({"source": source.facts(), **counts}, indent=2, default=str))
    else:
        print("\n".join(stats_lines(source, counts)))
    return 0


def _filter(args: argparse.Namespace) -> int:
    from worldmind_local.memory.hub import new_folder, write_export
    from worldmind_local.memory.sources import open_source
    from worldmind_local.memory.tools import filter_repository, parse_range

    new_folder(args.out)
    episodes = parse_range(args.episodes)
    source, repo = open_source(args.source)
    kept = filter_repository(source, repo, partitions=_list(args.partition), benchmarks=_list(args.benchmark),
                             models=_list(args.model), episodes=episodes)
    out = write_export(kept, args.out)
    print(f"kept {kept.table.num_rows} of {source.entries} entries -> {out}")
    return 0


def _merge(args: argparse.Namespace) -> int:
    from worldmind_local.memory.hub import new_folder, write_export
    from worldmind_local.memory.sources import open_source
    from worldmind_local.memory.tools import merge

    new_folder(args.out)
    inputs = [open_source(value) for value in args.sources]
    merged, dropped = merge(inputs, dedup_threshold=args.dedup_threshold)
    out = write_export(merged, args.out)
    total = sum(source.entries for source, _ in inputs)
    print(f"merged {len(inputs)} repositories: {merged.table.num_rows} of {total} entries kept "
          f"({sum(dropped.values())} near-duplicates dropped) -> {out}")
    for value, n in dropped.items():
        print(f"  {value}: {n} dropped")
    return 0


def _diff(args: argparse.Namespace) -> int:
    from worldmind_local.memory.sources import open_source
    from worldmind_local.memory.tools import diff, diff_lines

    sa, a = open_source(args.a)
    sb, b = open_source(args.b)
    result = diff(a, b)
    print("\n".join(diff_lines(sa, sb, result, limit=args.limit)))
    return 0 if not (result["only_a"] or result["only_b"] or result["changed"] or result["settings"]) else 1
