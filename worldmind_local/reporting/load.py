"""Run folders -> streams a report can group: each stream's spec, facts and episode records.

Reads what a run writes (manifest.json, results.json, streams/<id>/episodes.jsonl, poison.json) and
nothing else; every field that newer runs add (perturb, task_order_seed, memory_sources) is read with a
default, so a report works over old and new runs together. `episodes.jsonl` is the source of truth for
the numbers; results.json and manifest.json give the specs and facts.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Stream", "Run", "load_runs", "IDENTITY_FIELDS"]

# What makes two streams "the same experiment" across runs (the paper's stream identity).
IDENTITY_FIELDS = ("benchmark", "subset", "method", "options", "planner", "judge", "seed", "memory_from",
                   "memory_budget", "perturb", "task_order_seed")


@dataclass
class Stream:
    """One experiment stream of one run, with its records in episode order."""

    run: str
    stream_id: str
    spec: dict[str, Any]
    records: list[dict[str, Any]]
    status: str | None = None
    env: str = "twin"
    suite: str = ""
    memory_source: dict[str, Any] = field(default_factory=dict)
    poison: dict[str, Any] | None = None
    folder: Path | None = None

    def get(self, key: str, default: Any = None) -> Any:
        value = self.spec.get(key, default)
        return default if value is None else value

    @property
    def judge(self) -> str:
        return self.spec.get("judge") or self.spec.get("planner") or ""

    @property
    def identity(self) -> tuple[str, ...]:
        spec = {**self.spec, "judge": self.judge}
        return tuple(json.dumps(spec.get(k), sort_keys=True) for k in IDENTITY_FIELDS)

    @property
    def label(self) -> str:
        """The method as reports name it: the method plus any non-default options."""
        opts = self.spec.get("options") or {}
        if not opts:
            return str(self.spec.get("method"))
        return f"{self.spec.get('method')}[" + ",".join(f"{k}={v}" for k, v in sorted(opts.items())) + "]"


@dataclass
class Run:
    path: Path
    run_id: str
    manifest: dict[str, Any]
    results: dict[str, Any]
    streams: list[Stream]
    ignored: list[str] = field(default_factory=list)

    @property
    def env(self) -> str:
        return str((self.manifest.get("config") or {}).get("env") or "twin")


def _read_json(path: Path) -> dict[str, Any]:
    try:
        value = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) else {}


def _read_records(folder: Path) -> list[dict[str, Any]]:
    """Episode lines in file order (the order they ran); unreadable lines are skipped, never fatal."""
    path = folder / "episodes.jsonl"
    if not path.exists():
        return []
    out = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            value = json.loads(line)
        except ValueError:
            continue
        if isinstance(value, dict):
            out.append(value)
    return out


_SPEC_KEYS = ("benchmark", "subset", "method", "planner", "judge", "seed", "memory_from", "memory_budget",
              "limit", "options", "perturb", "task_order_seed")


def _specs(manifest: dict[str, Any], results: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """stream id -> spec, from results.json's streams, else from the manifest's config."""
    out: dict[str, dict[str, Any]] = {}
    for s in results.get("streams") or []:
        if isinstance(s, dict) and s.get("stream_id"):
            out[s["stream_id"]] = {k: s.get(k) for k in _SPEC_KEYS} | {"_status": s.get("status")}
    if out:
        return out
    from worldmind_local.runner.config import StreamSpec

    for raw in (manifest.get("config") or {}).get("streams") or []:
        try:
            spec = StreamSpec.model_validate(raw)
        except Exception:  # a spec this version cannot validate is still reported as written
            sid = None
        else:
            sid = spec.stream_id
        if sid:
            out[sid] = {k: raw.get(k) for k in _SPEC_KEYS} | {"method": spec.method, "options": spec.options}
    return out


def _memory_source(results: dict[str, Any], manifest: dict[str, Any], stream_id: str) -> dict[str, Any]:
    """Whatever provenance the run recorded for a stream's seed memory (format may vary: read defensively)."""
    for holder in (results.get("memory_sources"), manifest.get("memory_sources")):
        if isinstance(holder, dict) and isinstance(holder.get(stream_id), dict):
            return dict(holder[stream_id])
    return {}


def load_run(path: str | Path) -> Run:
    root = Path(path)
    if not (root / "streams").is_dir() and not (root / "manifest.json").exists():
        raise FileNotFoundError(f"{root}: not a run folder (no manifest.json or streams/)")
    manifest = _read_json(root / "manifest.json")
    results = _read_json(root / "results.json")
    run_id = str(results.get("run_id") or manifest.get("run_id") or root.name)
    env = str((manifest.get("config") or {}).get("env") or "twin")
    data = manifest.get("data") or {}
    streams = []
    for sid, spec in _specs(manifest, results).items():
        folder = root / "streams" / sid
        status = spec.pop("_status", None) or _read_json(folder / "status.json").get("status")
        poison = _read_json(folder / "poison.json") or None
        streams.append(Stream(
            run=run_id, stream_id=sid, spec=spec, records=_read_records(folder), status=status, env=env,
            suite=str((data.get(sid) or {}).get("suite") or ""),
            memory_source=_memory_source(results, manifest, sid), poison=poison, folder=folder,
        ))
    return Run(root, run_id, manifest, results, streams)


def load_runs(paths: Iterable[str | Path]) -> list[Run]:
    """Load runs; a stream whose identity an earlier run already holds is listed in `ignored` (the first
    one wins, so the order of RUN arguments decides)."""
    runs, seen = [], set()
    for path in paths:
        run = load_run(path)
        kept = []
        for s in run.streams:
            if s.identity in seen:
                run.ignored.append(s.stream_id)
                continue
            seen.add(s.identity)
            kept.append(s)
        run.streams = kept
        runs.append(run)
    return runs
