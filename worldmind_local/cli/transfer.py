"""`worldmind transfer`: the paper's transfer matrix (cross-model and cross-environment) as one command.

Each source (planner x memory benchmark) builds its repository in a stream of its own; every target
(planner x benchmark x subset) runs from scratch and once seeded from each source's repository
(`memory_from: stream:<source id>`). All streams run concurrently on shared backends; a seeded stream
waits for its source stream (on the first run and on resume alike), and re-running the same command
resumes everything. A source on a target's own benchmark and subset with the target's planner *is* that
target's from-scratch stream, so it runs once. The table has one row per target and seed memory, with
`memory_from` (source model/benchmark#hash) and the gain over the target's from-scratch row.

Experiment-file form (`--plan transfer.yaml`):

```yaml
transfer:
  benchmarks: [eb_alfred]                 # targets
  planners: [hf:smollm2-135m-instruct, hf:tiny-qwen3]
  memory_benchmarks: [eb_alfred, eb_habitat]   # sources (default: the targets' benchmarks)
  subsets: [base]                         # target subsets (default base)
  source_subset: base                     # the subset each source stream runs
  method: worldmind
  limit: 10
  options: {top_k: 2}
run: {suite: generated, suite_size: 10}   # RunConfig fields
out: runs/transfer
```
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

__all__ = ["register", "transfer_streams"]


def register(sub: Any) -> None:
    from worldmind_local.cli.run import DEFAULT_MODEL, _non_negative, _positive, add_method_flags

    p = sub.add_parser("transfer", help="the transfer matrix: sources build repositories, targets run "
                                        "from scratch and seeded from each", description=__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--benchmark", default="eb_alfred", help="comma list of target benchmarks")
    p.add_argument("--planners", default=DEFAULT_MODEL, help="comma list of planner model specs (targets and sources)")
    p.add_argument("--memory-benchmarks", default=None, help="comma list of source benchmarks (default: --benchmark)")
    p.add_argument("--subsets", default="base", help="comma list of target subsets (default base)")
    p.add_argument("--source-subset", default="base", help="the subset each source stream runs (default base)")
    p.add_argument("--method", default="worldmind", help="the method of every stream (default worldmind)")
    p.add_argument("--judge", default=None, help="judge model spec (default: each stream's planner)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--memory-budget", type=_non_negative, default=None, metavar="N")
    p.add_argument("--limit", type=_positive, default=None, metavar="N", help="first N episodes of each subset")
    p.add_argument("--plan", default=None, metavar="YAML", help="experiment file with a `transfer:` section")
    p.add_argument("--out", default=None, help="run folder (default runs/transfer-<benchmarks>)")
    p.add_argument("--data-dir", default=None)
    p.add_argument("--suite", default=None, choices=["embodiedbench", "generated"])
    p.add_argument("--suite-seed", type=int, default=0)
    p.add_argument("--suite-size", "--per-subset", dest="suite_size", type=_positive, default=50)
    p.add_argument("--env", default="twin", choices=["twin", "embodiedbench"])
    p.add_argument("--max-concurrency", type=_positive, default=None, metavar="N")
    p.add_argument("--no-cache", action="store_true")
    p.add_argument("--progress", choices=["auto", "bars", "lines"], default="auto")
    add_method_flags(p)
    p.set_defaults(func=main, default_model=DEFAULT_MODEL)


def _names(value: Any) -> list[str]:
    items = value if isinstance(value, list) else str(value or "").split(",")
    return [str(x).strip() for x in items if str(x).strip()]


def _check_subsets(benchmark: str, subsets: list[str]) -> None:
    from worldmind_local.data import adapter

    known = adapter(benchmark).subsets
    unknown = [s for s in subsets if s not in known]
    if unknown:
        raise ValueError(f"unknown subset(s) {', '.join(unknown)} for {benchmark}; known: {', '.join(known)}")


def transfer_streams(*, benchmarks: list[str], planners: list[str], memory_benchmarks: list[str],
                     subsets: list[str], source_subset: str, method: str, judge: str | None, seed: int,
                     limit: int | None, memory_budget: int | None, options: dict[str, Any]) -> list[Any]:
    """From-scratch streams (sources first, then targets not already among them), then every target
    seeded from every source, in that order (the order of the results table)."""
    from worldmind_local.runner.config import STREAM_REF, StreamSpec, _applicable

    if not benchmarks or not planners or not memory_benchmarks or not subsets:
        raise ValueError("transfer needs at least one benchmark, planner, memory benchmark and subset")
    for bench in benchmarks:
        _check_subsets(bench, subsets)
    for bench in memory_benchmarks:
        _check_subsets(bench, [source_subset])
    common = {"method": method, "judge": judge, "seed": seed, "limit": limit, "memory_budget": memory_budget,
              "options": _applicable(method, options)}
    sources = [StreamSpec(benchmark=b, subset=source_subset, planner=m, **common)
               for m in planners for b in memory_benchmarks]
    targets = [StreamSpec(benchmark=b, subset=s, planner=m, **common)
               for m in planners for b in benchmarks for s in subsets]
    scratch = list({s.stream_id: s for s in [*sources, *targets]}.values())
    seeded = [StreamSpec(benchmark=t.benchmark, subset=t.subset, planner=t.planner,
                         memory_from=f"{STREAM_REF}{src.stream_id}", **common)
              for t in targets for src in sources]
    return [*scratch, *seeded]


def build_config(args: argparse.Namespace) -> tuple[Any, str]:
    from worldmind_local.cli.run import method_options
    from worldmind_local.runner.config import RunConfig

    run_fields: dict[str, Any] = {"suite": args.suite, "data_dir": args.data_dir, "suite_seed": args.suite_seed,
                                  "suite_size": args.suite_size, "env": args.env, "cache": not args.no_cache}
    spec: dict[str, Any] = {
        "benchmarks": args.benchmark, "planners": args.planners, "memory_benchmarks": args.memory_benchmarks,
        "subsets": args.subsets, "source_subset": args.source_subset, "method": args.method, "judge": args.judge,
        "seed": args.seed, "limit": args.limit, "memory_budget": args.memory_budget, "options": method_options(args),
    }
    out = args.out
    if args.plan:
        plan, run = _read_plan(args.plan)
        spec.update({k: v for k, v in plan.items() if k != "out"})
        run_fields.update(run)
        out = out or plan.get("out")
    streams = transfer_streams(
        benchmarks=_names(spec["benchmarks"]), planners=_names(spec["planners"]),
        memory_benchmarks=_names(spec["memory_benchmarks"]) or _names(spec["benchmarks"]),
        subsets=_names(spec["subsets"]), source_subset=str(spec["source_subset"]), method=str(spec["method"]),
        judge=spec["judge"], seed=int(spec["seed"]), limit=spec["limit"], memory_budget=spec["memory_budget"],
        options=dict(spec["options"] or {}),
    )
    out = out or f"runs/transfer-{'+'.join(_names(spec['benchmarks']))}"
    return RunConfig(streams=streams, **run_fields), str(out)


def _read_plan(path: str) -> tuple[dict[str, Any], dict[str, Any]]:
    import yaml

    try:
        raw = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: cannot read experiment file: {' '.join(str(exc).split())}") from None
    if not isinstance(raw, dict) or not isinstance(raw.get("transfer"), dict):
        raise ValueError(f"{path}: field 'transfer': expected a mapping (benchmarks, planners, ...)")
    known = {"benchmarks", "planners", "memory_benchmarks", "subsets", "source_subset", "method", "judge", "seed",
             "limit", "memory_budget", "options", "out"}
    unknown = sorted(set(raw["transfer"]) - known)
    if unknown:
        raise ValueError(f"{path}: field 'transfer.{unknown[0]}': unknown; known: {', '.join(sorted(known))}")
    run = raw.get("run") or {}
    if not isinstance(run, dict):
        raise ValueError(f"{path}: field 'run': expected a mapping of run settings")
    plan = dict(raw["transfer"])
    if raw.get("out") and "out" not in plan:
        plan["out"] = raw["out"]
    return plan, run


def main(args: argparse.Namespace) -> int:
    import asyncio

    from worldmind_local.report import format_results
    from worldmind_local.runner.run import run_experiment

    try:
        config, out = build_config(args)
    except (ValueError, KeyError) as exc:
        print(f"worldmind transfer: {exc}", file=sys.stderr)
        return 2
    seeded = sum(1 for s in config.streams if s.memory_from)
    print(f"worldmind transfer: {len(config.streams) - seeded} from-scratch and {seeded} seeded stream(s) "
          f"-> {out}", file=sys.stderr)
    progress = {"auto": None, "bars": True, "lines": False}[args.progress]
    result = asyncio.run(run_experiment(config, out, max_concurrency=args.max_concurrency, progress=progress))
    print(format_results(result.results))
    print(f"\nrun folder: {result.run_dir.root}")
    return 1 if result.failed else 0
