"""Retrieval latency of the World Knowledge Repository per planning step, at several repository sizes.

One step = what WorldMind does before each planner call: top-k Process Experience plus top-k Goal
Experience (excluding the current instruction), against a repository of N entries split evenly between
the partitions. The query embedding is computed once per episode, so it is timed separately and left
out of the per-step figure (the paper reports 2.8 ms per step; the target here is <= 0.1 ms at 1,000).
The repository holds random unit vectors (only the cost matters); the query is a real all-MiniLM-L6-v2
embedding unless --random-query.

    .venv/bin/python scripts/bench_retrieval.py [--sizes 50,1000,100000] [--k 2] [--random-query]

The last line printed is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

TARGET_MS_AT_1000 = 0.1
INSTRUCTION = "Put a washed apple in the refrigerator."


def build_repository(n: int, dim: int, model_id: str, seed: int = 0):  # noqa: ANN201 - lazy import
    """N entries (alternating process/goal) with random unit embeddings, through the public load path."""
    from datasets import Dataset

    from worldmind_local.memory import WorldKnowledgeRepository
    from worldmind_local.memory.entries import ExperienceEntry
    from worldmind_local.memory.storage import build_dataset

    rng = np.random.default_rng(seed)
    vectors = rng.standard_normal((2, n, dim), dtype=np.float32)
    vectors /= np.linalg.norm(vectors, axis=2, keepdims=True)
    entries = [
        ExperienceEntry.model_construct(
            id=f"e{i}", partition="process" if i % 2 == 0 else "goal", text=f"experience {i}",
            instruction=INSTRUCTION if i % 97 == 0 else f"task {i % 500}", benchmark="eb_alfred",
            subset="base", episode=i, task_id=f"t{i}", step=None, action=None, predicted_state=None,
            actual_state=None, judge_reason=None, planner_model="", judge_model="", run_id="bench",
            key_embedding=None, text_embedding=None,
        )
        for i in range(n)
    ]
    meta = {"embedder_model_id": model_id, "dim": dim, "dedup_threshold": 0.95, "budget": None}
    dataset: Dataset = build_dataset(entries, vectors[0], vectors[1], meta)
    return WorldKnowledgeRepository.from_dataset(dataset)


def time_steps(repo, query: np.ndarray, k: int, reps: int) -> np.ndarray:  # noqa: ANN001
    """Seconds per step over `reps` steps (after a short warm-up)."""
    def step() -> None:
        repo.retrieve(query, "process", k)
        repo.retrieve(query, "goal", k, exclude_instruction=INSTRUCTION)

    for _ in range(min(50, reps)):
        step()
    out = np.empty(reps)
    for i in range(reps):
        t0 = time.perf_counter()
        step()
        out[i] = time.perf_counter() - t0
    return out


def query_embedding(random_query: bool, dim: int) -> tuple[np.ndarray, float | None, str]:
    if random_query:
        q = np.random.default_rng(1).standard_normal(dim).astype(np.float32)
        return q / np.linalg.norm(q), None, "random"
    from worldmind_local.memory import Embedder

    embedder = Embedder()
    embedder.encode(["warm-up"])               # model load, not part of a query
    t0 = time.perf_counter()
    q = embedder.encode([INSTRUCTION])[0]
    return q, (time.perf_counter() - t0) * 1e3, embedder.model_id


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="50,1000,100000", help="comma list of repository sizes")
    parser.add_argument("--k", type=int, default=2, help="entries retrieved per partition (paper: 2)")
    parser.add_argument("--random-query", action="store_true", help="skip the real embedder")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]

    from worldmind_local.memory import DEFAULT_DIM, DEFAULT_MODEL_ID

    query, embed_ms, query_source = query_embedding(args.random_query, DEFAULT_DIM)
    rows = {}
    print(f"{'entries':>9} {'median ms':>10} {'p90 ms':>8} {'build s':>8}")
    for n in sizes:
        t0 = time.perf_counter()
        repo = build_repository(n, DEFAULT_DIM, DEFAULT_MODEL_ID)
        build_s = time.perf_counter() - t0
        secs = time_steps(repo, query, args.k, reps=2000 if n <= 10_000 else 300)
        med, p90 = float(np.median(secs) * 1e3), float(np.percentile(secs, 90) * 1e3)
        rows[str(n)] = {"median_ms": round(med, 5), "p90_ms": round(p90, 5), "build_s": round(build_s, 3)}
        print(f"{n:>9} {med:>10.4f} {p90:>8.4f} {build_s:>8.2f}")
    at_1000 = rows.get("1000", {}).get("median_ms")
    print(json.dumps({
        "bench": "retrieval", "k": args.k, "step": "process top-k + goal top-k (self-excluded)",
        "sizes": rows, "query": query_source,
        "query_embedding_ms": None if embed_ms is None else round(embed_ms, 3),
        "target_ms_at_1000": TARGET_MS_AT_1000,
        "meets_target": None if at_1000 is None else at_1000 <= TARGET_MS_AT_1000,
    }))


if __name__ == "__main__":
    main()
