"""`--perturb poison:RATE`: the paper's memory-poisoning stress test ("at WKR load time, randomly replaces
20% of stored experiences with predefined garbage rules that are structurally similar but semantically
incorrect").

- When: once, on the stream's *initial* repository (the one `--memory-from` loads), right after it is
  loaded, before the first episode. Experience the stream writes afterwards is its own and stays clean;
  poisoning it later would make a resumed run differ from an uninterrupted one. A stream that starts
  from an empty memory has nothing to poison (the run says so on stderr).
- What: `round(RATE * n)` of the n entries, chosen by numpy's seeded RNG (the stream's seed), each
  replaced by a rule drawn from `poison_rules.json` (a wrong precondition for a Process Experience, a
  wrong-order workflow for a Goal Experience), filled with the benchmark's own object names. The
  entry keeps its instruction (so it is retrieved exactly where the original would have been), its
  partition and provenance; its text, text embedding and id change.
- Record: `streams/<id>/poison.json` lists every poisoned position with the original entry and its
  replacement, so a report says exactly which entries were poisoned.
"""

from __future__ import annotations

import functools
import json
import math
import random
import sys
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["parse_perturb", "poison_rate", "poison_indices", "poisoned_text", "poison_memory", "with_poison",
           "POISON_FILE"]

POISON_FILE = "poison.json"


def parse_perturb(value: str | None) -> str | None:
    """The canonical spelling of a `--perturb` value: None, "rename" or "poison:RATE" with 0 < RATE <= 1."""
    if value is None or value == "":
        return None
    text = str(value).strip().lower()
    if text == "rename":
        return "rename"
    if text.startswith("poison:"):
        raw = text.split(":", 1)[1].strip()
        try:
            rate = float(raw[:-1]) / 100 if raw.endswith("%") else float(raw)
        except ValueError:
            raise ValueError(f"perturb {value!r}: RATE must be a number in (0, 1], e.g. poison:0.2") from None
        if not (0.0 < rate <= 1.0) or not math.isfinite(rate):
            raise ValueError(f"perturb {value!r}: RATE must be in (0, 1], got {rate}")
        return f"poison:{rate:g}"
    raise ValueError(f"perturb {value!r}: expected 'rename' or 'poison:RATE' (0 < RATE <= 1)")


def poison_rate(perturb: str | None) -> float | None:
    canonical = parse_perturb(perturb)
    return float(canonical.split(":", 1)[1]) if canonical and canonical.startswith("poison:") else None


@functools.lru_cache(maxsize=1)
def _templates() -> dict[str, list[str]]:
    text = resources.files("worldmind_local.perturb").joinpath("poison_rules.json").read_text()
    return {k: v for k, v in json.loads(text).items() if not k.startswith("_")}


def poison_indices(n: int, rate: float, seed: int) -> list[int]:
    """Which of n entries are poisoned: round(rate * n) distinct positions, sorted, the same per seed."""
    k = min(n, int(math.floor(rate * n + 0.5)))
    if k == 0:
        return []
    return sorted(int(i) for i in np.random.default_rng(int(seed)).choice(n, size=k, replace=False))


def poisoned_text(partition: str, benchmark: str, seed: int, position: int) -> str:
    """A wrong rule shaped like a real entry of `partition`, from a seeded draw over the templates and
    the benchmark's object names (the rename table's keys)."""
    from worldmind_local.perturb.rename import rename_table

    try:
        names = sorted(rename_table(benchmark))
    except KeyError:
        names = ["cabinet", "table", "sink", "counter", "fridge"]
    templates = _templates()["process" if partition == "process" else "goal"]
    rng = random.Random(f"worldmind-poison:{seed}:{position}")
    a, b, c = rng.sample(names, 3)
    return rng.choice(templates).format(a=a, b=b, c=c)


def poison_memory(memory: Any, *, rate: float, seed: int, benchmark: str,
                  embedder: Any | None = None) -> tuple[Any, dict[str, Any]]:
    """A copy of `memory` with `round(rate * n)` entries replaced by poisoned rules, and the record of
    what was replaced. Works on any memory with `to_dataset()` / `from_dataset()` (the WKR and the
    baselines' stores); the copy keeps the memory's settings and commit log."""
    import datasets

    dataset = memory.to_dataset()
    rows = dataset.to_list()
    chosen = poison_indices(len(rows), rate, seed)
    report: dict[str, Any] = {"rate": rate, "seed": seed, "entries": len(rows), "poisoned": len(chosen),
                              "replaced": []}
    if not chosen:
        return memory, report
    for position in chosen:
        row = rows[position]
        partition = str(row.get("partition") or "goal")
        text = poisoned_text(partition, benchmark, seed, position)
        original = {k: v for k, v in row.items() if not k.endswith("_embedding")}
        row.update({"text": text, "id": ""})
        if "text_embedding" in row:
            row["text_embedding"] = None   # recomputed for the new text on load
        report["replaced"].append({"position": position, "original": original, "poisoned_text": text})
    poisoned = datasets.Dataset.from_list(rows, features=dataset.features, info=dataset.info)
    new = type(memory).from_dataset(poisoned, embedder, where="poisoned memory")
    ids = [e.id for e in new.entries()]
    for item in report["replaced"]:
        item["poisoned_id"] = ids[item["position"]]
    return new, report


def with_poison(make_memory: Callable[[], Any], perturb: str | None, *, seed: int, benchmark: str,
                stream_root: str | Path, embedder: Any | None = None, stream_id: str = "") -> Callable[[], Any]:
    """`make_memory` with poisoning applied to the memory it returns (unchanged unless perturb is
    poison:RATE). The record goes to `stream_root/poison.json` each time (the same every time)."""
    rate = poison_rate(perturb)
    if rate is None:
        return make_memory

    def make() -> Any:
        memory = make_memory()
        if memory is None or not len(memory):
            print(f"worldmind run: stream {stream_id}: --perturb {perturb} has nothing to poison (the stream "
                  f"starts from an empty memory; give it --memory-from)", file=sys.stderr)
            return memory
        memory, report = poison_memory(memory, rate=rate, seed=seed, benchmark=benchmark, embedder=embedder)
        root = Path(stream_root)
        root.mkdir(parents=True, exist_ok=True)
        (root / POISON_FILE).write_text(json.dumps(report, indent=2, ensure_ascii=False, default=str) + "\n")
        return memory

    return make
