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
    p.add_argument("--memory-from", default=None, metavar="SOURCE",
                   help="start from this repository (transfer): a run folder, a stream's memory/, an export, "
                        "a parquet file or folder, hub:OWNER/NAME[@REV] (local Hub cache), or stream:<id>; "
                        "recorded by content hash")
    p.add_argument("--memory-budget", type=_non_negative, default=None, metavar="N",
                   help="cap the repository at N experiences (MemN; unit: the method's budget_unit)")
    p.add_argument("--limit", type=_positive, default=None, metavar="N", help="first N episodes of each subset")
    p.add_argument("--perturb", default=None, metavar="rename|poison:RATE",
                   help="stress test: rename = object names in env feedback replaced by synonyms (actions and "
                        "state untouched); poison:RATE = that share of the --memory-from repository replaced "
                        "by wrong rules at load time (see worldmind_local/perturb)")
    p.add_argument("--task-order-seed", default=None, metavar="S[,S...]",
                   help="run each stream's episodes in a seeded permutation (one stream per seed given)")
    p.add_argument("--out", default=None, help="run folder (default runs/<benchmark>-<method>-<planner>)")
    p.add_argument("--plan", default=None, metavar="YAML", help="experiment file listing streams (see docs)")
    p.add_argument("--data-dir", default=None, help="EmbodiedBench data (default $WORLDMIND_DATA, then "
                   "~/.cache/worldmind/embodiedbench)")
    p.add_argument("--suite", default=None, choices=["embodiedbench", "generated"],
                   help="task suite (default: EmbodiedBench data if present, else generated)")
    p.add_argument("--suite-seed", type=int, default=0, help="seed of the generated suite")
    p.add_argument("--suite-size", "--per-subset", dest="suite_size", type=_positive, default=50,
                   help="episodes per subset of the generated suite (default 50)")
    p.add_argument("--env", default="twin", choices=["twin", "embodiedbench"], help="simulator backend")
    p.add_argument("--env-workers", default="auto", choices=["auto", "inline", "process", "ray"],
                   help="where each stream's env runs: on the event loop, in a process of its own, or as a "
                        "Ray actor (default auto: inline for the twins, process for --env embodiedbench)")
    p.add_argument("--ray-address", default=None, metavar="ADDR",
                   help="Ray cluster for --env-workers ray (default: $RAY_ADDRESS, else a local cluster)")
    p.add_argument("--env-step-timeout", type=float, default=None, metavar="S",
                   help="seconds before a worker's step counts as hung (default per benchmark, 60)")
    p.add_argument("--env-failure", default="replay", choices=["replay", "error"],
                   help="a worker that dies or hangs is restarted; replay: the episode goes on where it was "
                        "(its steps re-run and checked); error: the episode is recorded as an error")
    p.add_argument("--env-worker-option", action="append", default=[], metavar="KEY=VALUE",
                   help="worker setting, repeatable: displays=:0,:1 gpus=0,1 ray_num_gpus=0.25 "
                        "ray_num_cpus=1 ray_resources=display:1 frame_codec=png max_restarts=2 (see README)")
    add_method_flags(p)
    p.add_argument("--wave", type=int, default=1, metavar="N",
                   help="N episodes of a stream at once on a memory snapshot (deviation from the paper)")
    p.add_argument("--max-concurrency", type=_positive, default=None, metavar="N",
                   help="bound in-flight model requests (>= 1; default unbounded)")
    p.add_argument("--no-cache", action="store_true", help="do not record responses in OUT/cache.sqlite")
    p.add_argument("--progress", choices=["auto", "bars", "lines", "streams"], default="auto",
                   help="one overall bar (auto/bars on a terminal, plain lines otherwise); streams: also "
                        "one bar (or one line per episode) per stream")
    p.set_defaults(func=main)


def _positive(value: str) -> int:
    n = _integer(value)
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return n


def _non_negative(value: str) -> int:
    n = _integer(value)
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return n


def _integer(value: str) -> int:
    try:
        return int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {value!r}") from None


def _method_config_fields() -> dict[str, Any]:
    """Every option of every registered method's config: name -> pydantic FieldInfo (first wins)."""
    from worldmind_local.registry import METHODS

    fields: dict[str, Any] = {}
    for name in METHODS.names():
        for key, info in METHODS.get(name).config_class.model_fields.items():
            fields.setdefault(key, info)
    return fields


def add_method_flags(p: argparse.ArgumentParser) -> None:
    """One flag per method option, generated from the methods' pydantic configs (`--top-k 3`,
    `--judge-feedback/--no-judge-feedback`, ...); unset flags leave the method's default. An option
    applies to the methods that have it; experiment files set the same fields under `options`."""
    import typing

    group = p.add_argument_group("method options (from the methods' configs; see `worldmind methods list`)")
    for key, info in _method_config_fields().items():
        flag = "--" + key.replace("_", "-")
        annotation = info.annotation
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        base = args[0] if args and typing.get_origin(annotation) is not typing.Literal else annotation
        help_text = (info.description or key) + f" (default {info.default})"
        if base is bool:
            group.add_argument(flag, dest=f"opt_{key}", action=argparse.BooleanOptionalAction, default=None,
                               help=help_text)
        elif typing.get_origin(annotation) is typing.Literal:
            group.add_argument(flag, dest=f"opt_{key}", choices=list(typing.get_args(annotation)), default=None,
                               help=help_text)
        else:
            kind = base if base in (int, float) else str
            group.add_argument(flag, dest=f"opt_{key}", type=kind, default=None, help=help_text)


def method_options(args: argparse.Namespace) -> dict[str, Any]:
    return {k[4:]: v for k, v in vars(args).items() if k.startswith("opt_") and v is not None}


def _key_values(items: list[str], flag: str) -> dict[str, str]:
    """`KEY=VALUE` flags as a dict (values stay strings; the settings model parses them)."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"{flag} expects KEY=VALUE, got {item!r}")
        out[key.strip()] = value.strip()
    return out


def _int_list(value: str, flag: str) -> list[int]:
    try:
        return [int(x) for x in value.split(",") if x.strip()]
    except ValueError as exc:
        raise ValueError(f"{flag} expects a comma list of integers, got {value!r}") from exc


def build_config(args: argparse.Namespace) -> tuple[Any, str]:
    from worldmind_local.data import adapter
    from worldmind_local.runner.config import (
        RunConfig,
        expand_streams,
        load_plan_file,
        split_list,
    )

    run_fields: dict[str, Any] = {
        "suite": args.suite, "data_dir": args.data_dir, "suite_seed": args.suite_seed,
        "suite_size": args.suite_size, "env": args.env, "wave": args.wave, "cache": not args.no_cache,
        "env_workers": args.env_workers, "ray_address": args.ray_address,
        "env_step_timeout": args.env_step_timeout, "env_failure": args.env_failure,
        "env_worker_options": _key_values(args.env_worker_option, "--env-worker-option"),
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
        options = method_options(args)
        methods = split_list(args.method)
        if not methods:
            raise ValueError("--method: give at least one method (see `worldmind methods list`)")
        from worldmind_local.registry import METHODS

        unknown_methods = [m for m in methods if m not in METHODS]
        if unknown_methods:
            raise ValueError(f"--method: unknown method(s) {', '.join(unknown_methods)}; "
                             f"known: {', '.join(METHODS.names())}")
        from worldmind_local.runner.config import method_class

        used = {k for m in methods for k in method_class(m).config_class.model_fields} | {
            "goal_experience", "process_experience", "verifier"}
        stray = sorted(set(options) - used)
        if stray:
            raise ValueError(f"option(s) {', '.join(stray)} apply to none of the methods {', '.join(methods)}")
        streams = expand_streams(
            benchmark=args.benchmark, subsets=subsets, methods=methods, planner=args.planner,
            judge=args.judge, seeds=_int_list(args.seed, "--seed"), memory_from=args.memory_from,
            memory_budget=args.memory_budget, limit=args.limit, options=options,
        )
        out = args.out or f"runs/{args.benchmark}-{'+'.join(methods)}-{args.planner.split(':', 1)[-1]}"
    return RunConfig(streams=_with_stress_tests(streams, args), **run_fields), out


def _with_stress_tests(streams: list[Any], args: argparse.Namespace) -> list[Any]:
    """--perturb and --task-order-seed applied to every stream (one copy per task-order seed)."""
    from worldmind_local.runner.config import StreamSpec

    perturb, order_text = getattr(args, "perturb", None), getattr(args, "task_order_seed", None)
    orders = _int_list(order_text, "--task-order-seed") if order_text else []
    if perturb is None and not orders:
        return streams
    out = []
    for spec in streams:
        base = spec.model_dump()
        if perturb is not None:
            base["perturb"] = perturb
        for order in orders or [base.get("task_order_seed")]:
            out.append(StreamSpec(**{**base, "task_order_seed": order}))
    return out


def main(args: argparse.Namespace) -> int:
    import asyncio

    from worldmind_local.report import format_results
    from worldmind_local.runner.run import run_experiment

    try:
        config, out = build_config(args)
    except (ValueError, KeyError) as exc:
        print(f"worldmind run: {exc}", file=sys.stderr)
        return 2
    from worldmind_local.runner.progress import quiet_model_loading

    quiet_model_loading()  # no "Loading weights" bars from transformers/sentence-transformers by default
    progress = {"auto": None, "bars": True, "lines": False, "streams": "streams"}[args.progress]
    print(f"worldmind run: {len(config.streams)} stream(s) -> {out}", file=sys.stderr)
    result = asyncio.run(run_experiment(config, out, max_concurrency=args.max_concurrency, progress=progress))
    print(format_results(result.results, env=config.env))
    print(f"\nrun folder: {result.run_dir.root}  (results.json, streams/*/episodes.jsonl, streams/*/memory/)")
    return 1 if result.failed else 0
