"""`worldmind run`: run (or resume) experiment streams and write the run folder."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

DEFAULT_MODEL = "hf:smollm2-135m-instruct"


def register(sub: Any) -> None:
    p = sub.add_parser(
        "run",
        help="run WorldMind (or a baseline) on benchmark streams; re-running the same command resumes",
        description=(
            "Runs every stream (subset x method x seed, or the streams of --plan) concurrently on shared "
            "model backends. Writes OUT/manifest.json, OUT/streams/<id>/episodes.jsonl and memory/, "
            "OUT/results.json. Re-running the same command resumes: finished episodes are never re-run."
        ),
    )
    p.add_argument("--benchmark", default="eb_alfred", help="eb_alfred | eb_habitat | eb_navigation")
    p.add_argument("--subsets", default=None, help="comma list (default: every subset of the benchmark)")
    p.add_argument("--method", default="worldmind", help="comma list of methods (default: worldmind)")
    p.add_argument("--planner", default=DEFAULT_MODEL, help=f"model spec backend:name (default {DEFAULT_MODEL})")
    p.add_argument("--judge", default=None, help="model spec for judge/reflector (default: the planner)")
    p.add_argument("--seed", default="0", help="comma list of seeds (one stream per seed)")
    p.add_argument("--memory-from", default=None, metavar="PATH",
                   help="start from this WKR (a memory/ folder of another run): transfer experiments")
    p.add_argument("--memory-budget", type=int, default=None, metavar="N", help="cap the WKR at N entries (MemN)")
    p.add_argument("--limit", type=int, default=None, metavar="N", help="first N episodes of each subset")
    p.add_argument("--out", default=None, help="run folder (default runs/<benchmark>-<method>-<planner>)")
    p.add_argument("--plan", default=None, metavar="YAML", help="experiment file listing streams (see docs)")
    p.add_argument("--data-dir", default=None, help="EmbodiedBench data (default $WORLDMIND_DATA, then "
                   "~/.cache/worldmind/embodiedbench)")
    p.add_argument("--suite", default=None, choices=["embodiedbench", "generated"],
                   help="task suite (default: EmbodiedBench data if present, else generated)")
    p.add_argument("--suite-seed", type=int, default=0, help="seed of the generated suite")
    p.add_argument("--suite-size", "--per-subset", dest="suite_size", type=int, default=50,
                   help="episodes per subset of the generated suite (default 50)")
    p.add_argument("--env", default="twin", choices=["twin", "embodiedbench"], help="simulator backend")
    p.add_argument("--no-goal-experience", action="store_true", help="ablation: no Goal Experience")
    p.add_argument("--no-process-experience", action="store_true", help="ablation: no Process Experience")
    p.add_argument("--no-verifier", action="store_true", help="ablation: no judge (no predict-act-verify)")
    p.add_argument("--top-k", type=int, default=None, help="entries retrieved per partition (default per benchmark)")
    p.add_argument("--verify", default="first", choices=["first", "every"],
                   help="verify the first action of each plan (paper) or every executed action")
    p.add_argument("--max-plan-actions", type=int, default=None, metavar="N",
                   help="cap on actions per plan (default 20, as in the paper's prompt)")
    p.add_argument("--planner-max-tokens", type=int, default=None, metavar="N",
                   help="planner token budget (default 2048)")
    p.add_argument("--wave", type=int, default=1, metavar="N",
                   help="N episodes of a stream at once on a memory snapshot (deviation from the paper)")
    p.add_argument("--max-concurrency", type=int, default=None, metavar="N", help="bound in-flight model requests")
    p.add_argument("--no-cache", action="store_true", help="do not record responses in OUT/cache.sqlite")
    p.add_argument("--progress", choices=["auto", "bars", "lines"], default="auto")
    p.set_defaults(func=main)


def _int_list(value: str, flag: str) -> list[int]:
    try:
        return [int(x) for x in value.split(",") if x.strip()]
    except ValueError as exc:
        raise ValueError(f"{flag} expects a comma list of integers, got {value!r}") from exc


def build_config(args: argparse.Namespace) -> tuple[Any, str]:
    from worldmind_local.data import adapter
    from worldmind_local.runner.config import (
        MethodOptions,
        RunConfig,
        expand_streams,
        load_plan_file,
        split_list,
    )

    run_fields: dict[str, Any] = {
        "suite": args.suite, "data_dir": args.data_dir, "suite_seed": args.suite_seed,
        "suite_size": args.suite_size, "env": args.env, "wave": args.wave, "cache": not args.no_cache,
    }
    if args.plan:
        plan_run, streams = load_plan_file(args.plan)
        run_fields.update({k: v for k, v in plan_run.items() if k not in ("out",)})
        out = args.out or plan_run.get("out") or f"runs/{Path(args.plan).stem}"
    else:
        ad = adapter(args.benchmark)
        subsets = split_list(args.subsets) or list(ad.subsets)
        unknown = [s for s in subsets if s not in ad.subsets]
        if unknown:
            raise ValueError(f"unknown subset(s) {', '.join(unknown)} for {args.benchmark}; "
                             f"known: {', '.join(ad.subsets)}")
        options = MethodOptions(
            top_k=args.top_k, goal_experience=not args.no_goal_experience,
            process_experience=not args.no_process_experience, verifier=not args.no_verifier,
            verify=args.verify, max_plan_actions=args.max_plan_actions,
            planner_max_tokens=args.planner_max_tokens,
        )
        methods = split_list(args.method)
        streams = expand_streams(
            benchmark=args.benchmark, subsets=subsets, methods=methods, planner=args.planner,
            judge=args.judge, seeds=_int_list(args.seed, "--seed"), memory_from=args.memory_from,
            memory_budget=args.memory_budget, limit=args.limit, options=options,
        )
        out = args.out or f"runs/{args.benchmark}-{'+'.join(methods)}-{args.planner.split(':', 1)[-1]}"
    return RunConfig(streams=streams, **run_fields), out


def main(args: argparse.Namespace) -> int:
    import asyncio

    from worldmind_local.report import format_results
    from worldmind_local.runner.run import run_experiment

    config, out = build_config(args)
    progress = {"auto": None, "bars": True, "lines": False}[args.progress]
    print(f"worldmind run: {len(config.streams)} stream(s) -> {out}", file=sys.stderr)
    result = asyncio.run(run_experiment(config, out, max_concurrency=args.max_concurrency, progress=progress))
    print(format_results(result.results))
    print(f"\nrun folder: {result.run_dir.root}  (results.json, streams/*/episodes.jsonl, streams/*/memory/)")
    return 1 if result.failed else 0
