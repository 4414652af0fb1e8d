"""A whole run: build the shared backends and embedder once, run every stream concurrently, write results.

Every model call of every stream goes to one backend object per model spec, so the engine sees a full
batch (continuous batching on vLLM, the micro-batcher on hf). Streams never share memory or episode
order, so each stream's results equal those of running it alone with a deterministic backend.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import hashlib
import json
import logging
import shlex
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from worldmind_local.data import load_suite
from worldmind_local.env import Task
from worldmind_local.metrics import summarize_run
from worldmind_local.registry import BENCHMARKS, METHODS
from worldmind_local.runner.artifacts import RunDir, file_fingerprint, git_sha, package_versions
from worldmind_local.runner.backends import LimitedBackend, role_backends
from worldmind_local.runner.config import RunConfig, StreamSpec
from worldmind_local.runner.progress import Progress
from worldmind_local.runner.stream import StreamOutcome, StreamRunner

__all__ = ["run_experiment", "RunResult"]

log = logging.getLogger(__name__)


class RunResult:
    def __init__(self, run_dir: RunDir, outcomes: list[StreamOutcome], results: dict[str, Any]) -> None:
        self.run_dir = run_dir
        self.outcomes = outcomes
        self.results = results

    @property
    def failed(self) -> list[StreamOutcome]:
        return [o for o in self.outcomes if o.status != "finished"]


def _suite_tasks(config: RunConfig, spec: StreamSpec) -> tuple[list[Task], str]:
    suite = load_suite(
        spec.benchmark, data_dir=config.data_dir, suite=config.suite,
        seed=config.suite_seed, n_per_subset=config.suite_size,
    )
    tasks = suite.tasks(spec.subset)
    if spec.limit is not None:
        tasks = tasks[: spec.limit]
    from worldmind_local.perturb import permute

    tasks = permute(tasks, spec.task_order_seed)  # --task-order-seed: the same episodes in a seeded order
    return tasks, suite.describe()


def _tasks_hash(tasks: list[Task]) -> str:
    h = hashlib.sha256()
    for t in tasks:
        h.update(json.dumps([t.id, t.subset, t.index, t.instruction, t.payload], sort_keys=True,
                            default=str).encode())
    return h.hexdigest()


def _model_facts(addresses: list[str]) -> dict[str, Any]:
    from models.specs import load_spec

    facts: dict[str, Any] = {}
    for address in addresses:
        entry: dict[str, Any] = {}
        try:
            spec = load_spec(address)
            entry = {"model_id": spec.model_id, "backend": spec.backend, "dtype": spec.dtype}
            from models.weights import materialize  # cached folder; fast after the backend built it

            folder = Path(materialize(spec))
            files = sorted(p for p in folder.rglob("*") if p.is_file()) if folder.is_dir() else [folder]
            entry["files"] = {str(p.relative_to(folder) if folder.is_dir() else p.name): file_fingerprint(p)
                              for p in files}
        except Exception as exc:  # facts are best effort; a spec-less backend (replay) has no files
            entry.setdefault("note", f"no file fingerprint: {type(exc).__name__}: {exc}")
        facts[address] = entry
    return facts


def _protocol_facts(spec: StreamSpec, env: str) -> dict[str, Any]:
    """What the stream's models are shown and judged against (manifest.json `protocol`)."""
    cfg = spec.method_config()
    facts: dict[str, Any] = {"method": spec.method, "label": spec.label, "config": cfg.model_dump(mode="json"),
                             "observation_requested": cfg.observation}
    abstract_with = getattr(cfg, "abstract_with", None)
    if abstract_with == "vlm":
        facts["actual_state"] = "vlm_summary"
    elif abstract_with is not None:
        facts["actual_state"] = ("twin_symbolic_state (stand-in for the paper's VLM summary)" if env == "twin"
                                 else "simulator_metadata_text")
    return facts


def _load_saved(path: str, embedder: Any, spec: StreamSpec, method: Any) -> Any:
    """A stream's own saved memory/, with its commit log (unlike a --memory-from seed)."""
    cls = type(method.new_memory(embedder, spec.memory_budget))  # the method's own memory class
    return cls.load(path, embedder, budget=spec.memory_budget,
                    budget_unit=getattr(method.config, "budget_unit", "entries"))


def _memory_facts(source: Any, spec: StreamSpec) -> dict[str, Any]:
    """What a --memory-from source held (a `MemorySource`): content hash, resolved location, kind,
    entry counts, provenance, and whether it comes from another benchmark."""
    facts = source.facts()
    facts["benchmarks"] = list(source.provenance.get("benchmarks") or [])
    facts["cross_environment"] = any(b != spec.benchmark for b in facts["benchmarks"])
    facts["label"] = source.label
    return facts


def _seed_memory(spec: StreamSpec, method: Any, embedder: Any, run_dir: RunDir,
                 finished: Mapping[str, str]) -> tuple[Any, Any]:
    """A stream's seed memory and its `MemorySource`: another stream's `memory/` once that stream has
    finished (`stream:<id>`), or anything `--memory-from` accepts; the content must be what the run was
    set up with (`memory_sha256`), so a resumed run cannot silently start from a changed repository."""
    from worldmind_local.memory.sources import load_for_method

    assert spec.memory_from is not None
    if spec.seed_stream is not None:
        state = finished.get(spec.seed_stream)
        if state != "finished":
            raise ValueError(f"seed stream {spec.seed_stream} {state or 'did not run'}; stream {spec.stream_id} "
                             "starts only from a finished stream's memory")
        path = run_dir.stream(spec.seed_stream).memory_path
        if not path.is_dir():
            raise ValueError(f"seed stream {spec.seed_stream} has no memory/ (its method keeps no global memory)")
        memory, source = load_for_method(spec.memory_from, method, embedder, spec.memory_budget,
                                         kind="stream", path=path.resolve())
    else:
        memory, source = load_for_method(spec.memory_from, method, embedder, spec.memory_budget)
    if spec.memory_sha256 and source.sha256 != spec.memory_sha256:
        raise ValueError(f"--memory-from {spec.memory_from}: its content changed since this run was set up "
                         f"(sha256 {source.sha256[:12]}, the run expects {spec.memory_sha256[:12]})")
    return memory, source


def _in_seed_order(runners: list[StreamRunner], finished: dict[str, str]) -> list[Any]:
    """One coroutine per stream, all concurrent, except that a stream seeded from another stream
    (`memory_from: stream:<id>`) starts when that one has returned: on the first run and on resume alike
    (a finished source returns at once, its memory read from disk)."""
    done = {r.spec.stream_id: asyncio.Event() for r in runners}

    async def one(runner: StreamRunner) -> StreamOutcome:
        try:
            source = runner.spec.seed_stream
            if source is not None:
                await done[source].wait()
            outcome = await runner.run()
            finished[runner.spec.stream_id] = outcome.status
            return outcome
        finally:
            done[runner.spec.stream_id].set()

    return [one(r) for r in runners]


async def run_experiment(
    config: RunConfig,
    out: str | Path,
    *,
    max_concurrency: int | None = None,
    backends: Mapping[str, Any] | None = None,
    embedder: Any | None = None,
    progress: bool | None = None,
    on_episode: Callable[[StreamSpec, dict[str, Any]], None] | None = None,
    command: list[str] | None = None,
) -> RunResult:
    """Run (or resume) every stream of `config` into the run folder `out`.

    `backends` maps spec address -> ready ChatBackend (tests, or a caller that owns its engines);
    missing addresses are built with models.specs.make_backend.
    """
    run_dir = RunDir(out)
    run_id = run_dir.root.name
    tasks_by_stream: dict[str, list[Task]] = {}
    data_facts: dict[str, Any] = {}
    for spec in config.streams:
        BENCHMARKS.get(spec.benchmark)  # unknown benchmark -> clear KeyError before any work
        METHODS.get(spec.method)
        tasks, described = _suite_tasks(config, spec)
        tasks_by_stream[spec.stream_id] = tasks
        data_facts[spec.stream_id] = {"suite": described, "tasks_sha256": _tasks_hash(tasks), "episodes": len(tasks)}

    addresses = sorted({a for s in config.streams for a in (s.planner, s.judge_spec)})
    protocol = {s.stream_id: _protocol_facts(s, config.env) for s in config.streams}
    manifest = {
        "run_id": run_id,
        "started_at": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command": command or [Path(sys.argv[0]).name, *sys.argv[1:]],
        "command_line": shlex.join(command or sys.argv),
        "git_sha": git_sha(),
        "packages": package_versions(),
        "data": data_facts,
        "protocol": protocol,
    }
    from worldmind_local.runner.preflight import check_memory_source, check_model_specs, check_out_path

    # Everything a typo can break is checked before the run folder is created or locked.
    check_out_path(out)
    check_model_specs([a for a in addresses if a not in (backends or {})])
    for spec in config.streams:
        if spec.memory_from and spec.seed_stream is None:
            check_memory_source(spec.memory_from)
    with run_dir.lock():  # one process per run folder; a second one gets one line naming the holder
        resumed = run_dir.open(config.identity(), manifest)

        from worldmind_local.memory import Embedder

        built: dict[str, Any] = dict(backends or {})
        owned: list[Any] = []
        cache = None
        if config.cache:
            from models.cache import CachingBackend, ResponseCache

            cache = ResponseCache(run_dir.cache_path)
        for address in addresses:
            if address not in built:
                from models.specs import make_backend

                built[address] = make_backend(address)
                owned.append(built[address])
            if cache is not None:
                built[address] = CachingBackend(built[address], cache)
        if max_concurrency:
            limiter = asyncio.Semaphore(max_concurrency)
            built = {a: LimitedBackend(b, limiter) for a, b in built.items()}
        if not resumed or "models" not in (run_dir.read_manifest() or {}):
            run_dir.update_manifest(models=_model_facts(addresses))

        embedder = embedder if embedder is not None else Embedder()
        bars = Progress(enabled=progress)
        runners: list[StreamRunner] = []
        memory_sources: dict[str, Any] = {}
        finished: dict[str, str] = {}   # stream id -> status, once its run() returned (seeds wait for it)
        for spec in config.streams:
            from worldmind_local.methods.base import EpisodeContext
            from worldmind_local.perturb import perturbed_adapter, with_poison

            adapter = perturbed_adapter(BENCHMARKS.get(spec.benchmark), spec.perturb)  # --perturb rename
            method = METHODS.get(spec.method)(spec.method_config())

            def make_memory(_spec: StreamSpec = spec, _method: Any = method) -> Any:
                if not _spec.memory_from:
                    return _method.new_memory(embedder, _spec.memory_budget)
                memory, source = _seed_memory(_spec, _method, embedder, run_dir, finished)
                facts = _memory_facts(source, _spec)
                if facts["cross_environment"]:
                    foreign = [b for b in facts["benchmarks"] if b != _spec.benchmark]
                    print(f"worldmind run: stream {_spec.stream_id} starts from {_spec.memory_from}, which "
                          f"holds {', '.join(foreign)} experience (cross-environment transfer)", file=sys.stderr)
                memory_sources[_spec.stream_id] = facts
                return memory

            make_memory = with_poison(  # --perturb poison:RATE: applied to the memory make_memory returns
                make_memory, spec.perturb, seed=spec.seed, benchmark=spec.benchmark, embedder=embedder,
                stream_root=run_dir.stream(spec.stream_id).root, stream_id=spec.stream_id)

            def load_saved(path: str, _spec: StreamSpec = spec, _method: Any = method) -> Any:
                return _load_saved(path, embedder, _spec, _method)

            models, model_ids = role_backends(built, spec.planner, spec.judge_spec)

            def make_context(view: Any, *, _models=models, _ids=model_ids, _seed=spec.seed,
                             _cfg=method.config, _adapter=adapter) -> Any:
                return EpisodeContext(models=_models, model_ids=_ids, memory=view, embedder=embedder,
                                      run_id=run_id, seed=_seed, config=_cfg, adapter=_adapter,
                                      data_dir=config.data_dir)

            stream_dir = run_dir.stream(spec.stream_id)
            tasks = tasks_by_stream[spec.stream_id]
            bar = bars.add(spec.stream_id, total=len(tasks))

            def episode_done(s: StreamSpec, data: dict[str, Any], _bar=bar) -> None:
                _bar.update(data)
                if on_episode:
                    on_episode(s, data)

            runners.append(StreamRunner(
                spec, tasks=tasks, adapter=adapter, env_kind=config.env, method=method,
                make_context=make_context, make_memory=make_memory, load_saved=load_saved,
                stream_dir=stream_dir, wave=config.wave, on_episode=episode_done,
                env_workers=config.worker_settings(),
            ))
            bar.skip(len(stream_dir.read_episodes()))

        try:
            outcomes = list(await asyncio.gather(*_in_seed_order(runners, finished)))
        finally:
            bars.close()
            for backend in owned:
                await backend.aclose()
            if cache is not None:
                cache.close()
        results = summarize_run([
            {"stream_id": o.stream_id, "spec": o.spec.model_dump(mode="json"), "status": o.status,
             "error": o.error, "records": o.records}
            for o in outcomes
        ], memory_sources=memory_sources)
        results["run_id"] = run_id
        results["finished_at"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        results["memory_sources"] = memory_sources
        if memory_sources:
            run_dir.update_manifest(memory_sources=memory_sources)
        from worldmind_local.runner.schema import Manifest, Results

        results = Results.model_validate(results).model_dump(mode="json")
        Manifest.model_validate(run_dir.read_manifest())
        run_dir.write_results(results)
        return RunResult(run_dir, outcomes, results)
