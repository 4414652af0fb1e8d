"""Do env workers take slow simulators off the event loop? Streams of a twin made as slow as a real
simulator (`StepLatency`: a blocking sleep per step, as an AI2-THOR step blocks its caller), per worker
kind (inline, process, ray).

Each stream walks its own tasks' expert plans through `areset`/`astep`, exactly as the episode driver
calls an env. For each kind: the time for all N streams at once, and for the slowest stream (the one
with the most steps) alone; the target is N streams in at most 1.25x the slowest single stream (inline,
the steps of all streams queue on one loop: about Nx). Worker start-up (spawning the processes, placing
the Ray actors) is timed apart and reported, not hidden. A second pass with no latency gives the
per-step cost a worker adds (round trip, encoding) over the inline twin. Last line: one JSON object.

    python scripts/bench_envs.py [--latency 0.3] [--streams 8] [--episodes 2] [--kinds inline,process,ray]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time
from functools import partial
from typing import Any

TARGET = 1.25


def _tasks(benchmark: str, streams: int, episodes: int) -> list[list[Any]]:
    from worldmind_local.registry import BENCHMARKS

    adapter = BENCHMARKS.get(benchmark)
    tasks = [t for t in adapter.generate_tasks(0, adapter.subsets[0], streams * episodes * 2) if t.expert_plan]
    tasks = tasks[: streams * episodes]
    return [tasks[i * episodes:(i + 1) * episodes] for i in range(streams)]


def _envs(benchmark: str, kind: str, n: int, latency: float, ray_address: str | None) -> list[Any]:
    from worldmind_local.envworkers import StepLatency, WorkerSettings, make_env_worker
    from worldmind_local.registry import BENCHMARKS

    wrappers = (partial(StepLatency, step_seconds=latency),) if latency else ()
    settings = WorkerSettings(kind=kind, wrappers=wrappers, ray_address=ray_address)
    return [make_env_worker(BENCHMARKS.get(benchmark), "twin", settings, label=f"bench{i}") for i in range(n)]


async def _stream(env: Any, tasks: list[Any]) -> int:
    """One stream's episodes, as the driver steps them. Returns the number of steps."""
    areset = getattr(env, "areset", None)
    steps = 0
    for task in tasks:
        await areset(task) if areset else env.reset(task)
        for name in task.expert_plan:
            action = env.action_id(name)
            result = await env.astep(action) if areset else env.step(action)
            steps += 1
            if result.done:
                break
    return steps


async def _timed(envs: list[Any], work: list[list[Any]]) -> tuple[float, float, list[int]]:
    """(start-up seconds, episodes seconds, steps per stream) for these streams at once."""
    from worldmind_local.envworkers import close_env

    t0 = time.perf_counter()
    await asyncio.gather(*(env.start() for env in envs if hasattr(env, "start")))
    t1 = time.perf_counter()
    try:
        steps = list(await asyncio.gather(*(_stream(env, tasks) for env, tasks in zip(envs, work, strict=True))))
    finally:
        t2 = time.perf_counter()
        await asyncio.gather(*(close_env(env) for env in envs))
    return t1 - t0, t2 - t1, steps


async def scaling(benchmark: str, kind: str, work: list[list[Any]], latency: float,
                  ray_address: str | None) -> dict[str, Any]:
    steps_of = [sum(len(t.expert_plan) for t in tasks) for tasks in work]
    slowest = max(range(len(work)), key=lambda i: steps_of[i])
    single_start, single, _ = await _timed(_envs(benchmark, kind, 1, latency, ray_address), [work[slowest]])
    start, together, steps = await _timed(_envs(benchmark, kind, len(work), latency, ray_address), work)
    return {
        "kind": kind, "streams": len(work), "steps": steps, "latency_s": latency,
        "single_s": round(single, 3), "single_start_s": round(single_start, 3),
        "together_s": round(together, 3), "start_s": round(start, 3),
        "ratio": round(together / single, 3),
        "ratio_with_start": round((start + together) / (single_start + single), 3),
    }


async def overhead(benchmark: str, kind: str, work: list[list[Any]], ray_address: str | None,
                   repeats: int) -> dict[str, Any]:
    """Microseconds per step (resets included) with no latency, one stream, best of `repeats`."""
    env = _envs(benchmark, kind, 1, 0.0, ray_address)[0]
    tasks = [t for tasks in work for t in tasks]
    best = float("inf")
    from worldmind_local.envworkers import close_env

    try:
        if hasattr(env, "start"):
            await env.start()
        for _ in range(repeats):
            t0 = time.perf_counter()
            steps = await _stream(env, tasks)
            best = min(best, (time.perf_counter() - t0) / steps)
    finally:
        await close_env(env)
    return {"kind": kind, "us_per_step": round(best * 1e6, 1)}


def _start_ray(address: str | None) -> float:
    import ray

    t0 = time.perf_counter()
    ray.init(address=address, include_dashboard=False, log_to_driver=False, namespace="worldmind")
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--benchmark", default="eb_navigation")
    p.add_argument("--latency", type=float, default=0.3, help="seconds added to every step")
    p.add_argument("--streams", type=int, default=8)
    p.add_argument("--episodes", type=int, default=2, help="episodes per stream")
    p.add_argument("--kinds", default="inline,process,ray")
    p.add_argument("--ray-address", default=None)
    p.add_argument("--overhead-repeats", type=int, default=5)
    args = p.parse_args(argv)
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    if "ray" in kinds:
        try:
            print(f"ray: cluster up in {_start_ray(args.ray_address):.1f} s (not counted below)", file=sys.stderr)
        except ImportError:
            print("ray: not installed (make venv-ray); skipped", file=sys.stderr)
            kinds.remove("ray")
    work = _tasks(args.benchmark, args.streams, args.episodes)
    out: dict[str, Any] = {"benchmark": args.benchmark, "target_ratio": TARGET, "scaling": [], "overhead": []}
    print(f"{args.benchmark}: {args.streams} streams x {args.episodes} episodes, {args.latency} s per step")
    print(f"{'kind':8} {'start s':>8} {'N streams s':>12} {'slowest alone s':>16} {'ratio':>6} {'w/ start':>9}")
    for kind in kinds:
        row = asyncio.run(scaling(args.benchmark, kind, work, args.latency, args.ray_address))
        out["scaling"].append(row)
        print(f"{kind:8} {row['start_s']:8.2f} {row['together_s']:12.2f} {row['single_s']:16.2f} "
              f"{row['ratio']:6.2f} {row['ratio_with_start']:9.2f}", flush=True)
    print("per-step cost with no latency (resets included):")
    for kind in kinds:
        row = asyncio.run(overhead(args.benchmark, kind, work, args.ray_address, args.overhead_repeats))
        out["overhead"].append(row)
        print(f"{kind:8} {row['us_per_step']:10.1f} us/step", flush=True)
    print(json.dumps(out))
    worst = max((r["ratio"] for r in out["scaling"] if r["kind"] != "inline"), default=0.0)
    return 0 if worst <= TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
