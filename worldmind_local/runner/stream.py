"""One experiment stream: its episodes in order, one evolving memory, every finished episode on disk.

With `wave > 1` (opt-in, a documented deviation from the paper's protocol), `wave` consecutive episodes
run at once, each on its own copy of the memory as it stood before the wave; their experience is then
committed to the stream's memory in episode order, so the result is deterministic whatever order the
episodes finish in.
"""

from __future__ import annotations

import asyncio
import logging
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from worldmind_local.env import BenchmarkAdapter, Task
from worldmind_local.runner.artifacts import StreamDir
from worldmind_local.runner.config import StreamSpec

__all__ = ["StreamOutcome", "StreamRunner"]

log = logging.getLogger(__name__)


@dataclass
class StreamOutcome:
    stream_id: str
    spec: StreamSpec
    status: str  # "finished" | "failed"
    records: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None
    ran_episodes: int = 0
    seconds: float = 0.0


class StreamRunner:
    """Runs one stream. `make_memory()` builds its initial WKR; `make_context(memory)` the method's
    EpisodeContext for a memory view (the stream memory, or a wave's snapshot)."""

    def __init__(
        self,
        spec: StreamSpec,
        *,
        tasks: list[Task],
        adapter: BenchmarkAdapter,
        env_kind: str,
        method: Any,
        make_context: Callable[[Any], Any],
        make_memory: Callable[[], Any] | None,
        stream_dir: StreamDir,
        wave: int = 1,
        on_episode: Callable[[StreamSpec, dict[str, Any]], None] | None = None,
    ) -> None:
        self.spec = spec
        self.tasks = tasks
        self.adapter = adapter
        self.env_kind = env_kind
        self.method = method
        self.make_context = make_context
        self.make_memory = make_memory
        self.memory: Any | None = None
        self.dir = stream_dir
        self.wave = wave
        self.on_episode = on_episode
        self._envs: list[Any] = []

    # -- resume -----------------------------------------------------------------------------------

    def restore(self) -> list[dict[str, Any]]:
        """Finished episodes from disk, and the memory rebuilt from their experience in order."""
        records = self.dir.read_episodes()
        expected = [t.index for t in self.tasks[: len(records)]]
        got = [r.get("index") for r in records]
        if got != expected:
            raise ValueError(
                f"{self.dir.episodes_path}: episodes on disk (indices {got[:5]}...) do not match this "
                f"stream's task order {expected[:5]}...; the data or suite changed since the run started"
            )
        if self.memory is not None:
            for rec in records:
                self._commit(rec, recorded=True)
        return records

    def _commit(self, record: dict[str, Any], *, recorded: bool) -> None:
        """Apply an episode's experience to the stream memory, in the order it was produced."""
        from worldmind_local.memory import ExperienceEntry

        assert self.memory is not None
        for item in record.get("experience") or []:
            entry = ExperienceEntry(**{k: v for k, v in item.items() if k != "kept"})
            kept = self.memory.add_embedded(entry)
            if recorded and bool(item.get("kept")) != kept:
                log.warning("stream %s: replaying episode %s gave a different dedup decision for entry %s",
                            self.spec.stream_id, record.get("index"), entry.id)
            item["kept"] = kept

    # -- running ------------------------------------------------------------------------------------

    def _env(self, slot: int) -> Any:
        while len(self._envs) <= slot:
            self._envs.append(self.adapter.make_env(self.env_kind))
        return self._envs[slot]

    async def _episode(self, task: Task, slot: int, memory_view: Any) -> dict[str, Any]:
        ctx = self.make_context(memory_view)
        record = await self.method.run_episode(task, self._env(slot), ctx)
        data = record.model_dump(mode="json") if hasattr(record, "model_dump") else dict(record)
        data.setdefault("index", task.index)
        data["stream_id"] = self.spec.stream_id
        return data

    async def _save_memory(self) -> None:
        if self.memory is not None:
            await asyncio.to_thread(self.memory.save, self.dir.memory_path)

    def _finish_episode(self, data: dict[str, Any]) -> None:
        self.dir.append_episode(data)
        if self.on_episode:
            self.on_episode(self.spec, data)

    async def run(self) -> StreamOutcome:
        t0 = time.perf_counter()
        self.dir.ensure()
        outcome = StreamOutcome(self.spec.stream_id, self.spec, status="failed")
        try:
            # Built here, not by the caller: a stream whose memory cannot load fails alone.
            self.memory = self.make_memory() if self.make_memory else None
            records = self.restore()
            outcome.records = records
            if self.memory is not None and (records or not self.dir.memory_path.exists()):
                await self._save_memory()
            self.dir.write_status("running", done=len(records), total=len(self.tasks))
            pending = self.tasks[len(records):]
            for start in range(0, len(pending), self.wave):
                batch = pending[start: start + self.wave]
                if self.wave == 1:
                    data = await self._episode(batch[0], 0, self.memory)
                    results = [data]
                else:
                    views = [self.memory.copy() if self.memory is not None else None for _ in batch]
                    results = list(await asyncio.gather(
                        *(self._episode(task, slot, views[slot]) for slot, task in enumerate(batch))
                    ))
                    if self.memory is not None:
                        for data in results:
                            self._commit(data, recorded=False)
                for data in results:
                    self._finish_episode(data)
                    records.append(data)
                    outcome.ran_episodes += 1
                await self._save_memory()
                self.dir.write_status("running", done=len(records), total=len(self.tasks))
            outcome.status = "finished"
            self.dir.write_status("finished", done=len(records), total=len(self.tasks))
        except asyncio.CancelledError:
            self.dir.write_status("interrupted", done=len(outcome.records), total=len(self.tasks))
            raise
        except Exception as exc:  # a failing stream must not take the others down
            outcome.error = f"{type(exc).__name__}: {exc}"
            log.error("stream %s failed: %s", self.spec.stream_id, outcome.error)
            self.dir.write_status(
                "failed", error=outcome.error, traceback=traceback.format_exc(),
                done=len(outcome.records), total=len(self.tasks),
            )
        finally:
            for env in self._envs:
                close = getattr(env, "close", None)
                if close:
                    close()
            outcome.seconds = time.perf_counter() - t0
        return outcome
