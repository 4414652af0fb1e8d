"""Step cost of every registered benchmark's twin (target: at most 50 microseconds per step).

For each benchmark whose adapter imports, generate a suite and replay each task's own expert plan,
timing `env.step` only: not reset, not plan parsing, and not the observation text (it is rendered
lazily, so a step does not pay for it). Prints median and p90 microseconds per step per benchmark and,
last, one JSON line with all results.

    python scripts/bench_twin.py [--seed 0] [--per-subset 20] [--benchmark eb_alfred ...]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Sequence
from typing import Any

from worldmind_local.registry import BENCHMARKS

TARGET_US = 50.0


def _quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def bench(name: str, seed: int, per_subset: int, repeats: int) -> dict[str, Any]:
    adapter = BENCHMARKS.get(name)
    env = adapter.make_env("twin")
    step_ns: list[int] = []
    episodes = 0
    for subset in adapter.subsets:
        for task in adapter.generate_tasks(seed, subset, per_subset):
            if not task.expert_plan:
                continue
            episodes += 1
            for _ in range(repeats):
                env.reset(task)
                ids = [env.action_id(a) for a in task.expert_plan]
                for action in ids:
                    t0 = time.perf_counter_ns()
                    result = env.step(action)
                    step_ns.append(time.perf_counter_ns() - t0)
                    if result.done:
                        break
    env.close()
    if not step_ns:
        return {"episodes": episodes, "steps": 0}
    us = [n / 1000 for n in step_ns]
    return {
        "episodes": episodes,
        "steps": len(us),
        "median_us": round(statistics.median(us), 2),
        "p90_us": round(_quantile(us, 0.9), 2),
        "within_target": statistics.median(us) <= TARGET_US,
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--per-subset", type=int, default=20, help="generated tasks per subset")
    parser.add_argument("--repeats", type=int, default=3, help="replays of each episode")
    parser.add_argument("--benchmark", action="append", help="benchmark name (default: all registered)")
    args = parser.parse_args(argv)
    results: dict[str, Any] = {}
    for name in args.benchmark or BENCHMARKS.names():
        try:
            results[name] = bench(name, args.seed, args.per_subset, args.repeats)
        except Exception as exc:  # a benchmark that does not import yet must not hide the others
            results[name] = {"error": f"{type(exc).__name__}: {exc}"}
            print(f"{name}: skipped ({results[name]['error']})", file=sys.stderr)
            continue
        r = results[name]
        if r.get("steps"):
            print(f"{name}: median {r['median_us']} us/step, p90 {r['p90_us']} us/step "
                  f"over {r['steps']} steps in {r['episodes']} episodes (target <= {TARGET_US:.0f})")
    print(json.dumps({"bench": "twin_step_us", "seed": args.seed, "results": results}, sort_keys=True))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
