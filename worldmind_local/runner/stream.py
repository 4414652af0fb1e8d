"""One experiment stream: its episodes in order, one evolving memory, every finished episode on disk.

The runner is the only writer of a stream's memory. After an episode (or a wave of them) it embeds the
experience the method produced, adds it in episode order, marks the commit in the repository
(`commits`: episode index -> rows after it), saves `memory/` atomically, and only then appends the
episode line(s) to `episodes.jsonl` (a wave's lines in one write). So:

- `episodes.jsonl` holds no embeddings; the vectors live once, in the memory dataset;
- a kill between the memory save and the line append leaves a memory one commit ahead: resume cuts it
  back to the last recorded episode's commit (exact: entries are kept in insertion order);
- a kill in the middle of a wave's append leaves a partial wave: its lines are rolled back on resume
  (each line carries `wave: [first index, size]`), so the wave re-runs on the same snapshot.

With `wave > 1` (opt-in, a documented deviation from the paper's protocol), `wave` consecutive episodes
run at once, each on a snapshot of the memory as it stood before the wave; their experience is then
committed in episode order, so the result is deterministic whatever order the episodes finish in.
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

# Vector fields a memory entry may carry; records never store them (the memory dataset does).
EMBEDDING_FIELDS = ("key_embedding", "text_embedding")

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
    """Runs one stream. `make_memory()` builds its initial memory (None for an episodic method);
    `load_saved(path)` re-opens a saved `memory/`; `make_context(memory)` the method's EpisodeContext."""

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
        load_saved: Callable[[str], Any] | None = None,
        stream_dir: StreamDir,
        wave: int = 1,
        on_episode: Callable[[StreamSpec, dict[str, Any]], None] | None = None,
        env_workers: Any = None,
    ) -> None:
        self.spec = spec
        self.tasks = tasks
        self.adapter = adapter
        self.env_kind = env_kind
        self.method = method
        self.make_context = make_context
        self.make_memory = make_memory
        self.load_saved = load_saved
        self.memory: Any | None = None
        self.dir = stream_dir
        self.wave = wave
        self.on_episode = on_episode
        self._envs: list[Any] = []
        self.env_workers = env_workers  # envworkers.WorkerSettings: inline / process / ray (None: inline)
        self.gaps: list[Task] = []
        self.initial_rows = 0

    # -- resume -----------------------------------------------------------------------------------

    def _complete_waves(self, records: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Drop the lines of a wave that was only partly written (rolled back, re-run whole)."""
        if not records:
            return records
        wave = records[-1].get("wave")
        if not isinstance(wave, list) or len(wave) != 2:
            return records
        first, size = wave
        members = [r for r in records if r.get("wave") == wave]
        if len(members) >= size:
            return records
        log.warning("stream %s: rolling back a partly written wave of %d episode(s) starting at index %s",
                    self.spec.stream_id, len(members), first)
        keep = [r for r in records if r.get("wave") != wave]
        self.dir.rewrite_episodes(keep)
        return keep

    async def restore(self) -> list[dict[str, Any]]:
        """Finished episodes from disk, and the memory as it stood after the last of them."""
        records = self._complete_waves(self.dir.read_episodes())
        by_index = {t.index: t for t in self.tasks}
        order = {t.index: i for i, t in enumerate(self.tasks)}
        for rec in records:
            if rec.get("index") not in by_index:
                raise ValueError(f"{self.dir.episodes_path}: episode index {rec.get('index')} is not in this "
                                 f"stream's tasks; the data or suite changed since the run started")
        records.sort(key=lambda r: order[r["index"]])
        done = {r["index"] for r in records}
        last = order[records[-1]["index"]] if records else 0
        # Episodes missing before the last recorded one (a damaged line was quarantined): re-run alone.
        self.gaps = [t for t in self.tasks[:last] if t.index not in done]
        if self.memory is not None and records:
            restored = self._saved_memory(records)
            if restored is not None:
                self.memory = restored
            else:
                log.warning("stream %s: memory/ does not match episodes.jsonl; re-embedding the recorded "
                            "experience", self.spec.stream_id)
                await self._rebuild(records)
        return records

    def _saved_memory(self, records: list[dict[str, Any]]) -> Any | None:
        """The saved memory cut back to the last recorded episode's commit, or None if it cannot be."""
        saved = None
        if self.load_saved is not None and self.dir.memory_path.exists():
            try:
                saved = self.load_saved(str(self.dir.memory_path))
            except Exception as exc:  # a damaged memory/ is rebuilt from the records below
                log.warning("stream %s: %s is unreadable (%s); rebuilding it from episodes.jsonl",
                            self.spec.stream_id, self.dir.memory_path, exc)
        if saved is not None:
            commits = {int(i): rows for i, rows in saved.commits}
            last = records[-1]["index"]
            if all(r["index"] in commits for r in records) and last in commits:
                return saved.truncated(commits[last])
        return None

    async def _rerun_gap(self, task: Task) -> dict[str, Any]:
        """Re-run an episode whose line was lost (quarantined) on the memory as it stood before it.

        The saved memory already holds that episode's committed experience (memory/ is saved before a
        line is written), so nothing is committed again: the episode runs on a snapshot cut back to the
        commit before it, and its entries' `kept` flags are decided on that snapshot.
        """
        if self.memory is None:
            data, _ = await self._episode(task, 0, None)
            data["experience"] = []
            return data
        commits = [list(c) for c in self.memory.commits]
        at = next((i for i, c in enumerate(commits) if c[0] == task.index), None)
        if at is None:  # no record of its commit: run it on the current memory and commit normally
            log.warning("stream %s: episode %s has no commit in memory/; re-running it on the current memory",
                        self.spec.stream_id, task.index)
            data, experience = await self._episode(task, 0, self.memory)
            await self._commit(data, experience, task.index)
            return data
        rows = commits[at - 1][1] if at > 0 else self.initial_rows
        snapshot = self.memory.truncated(rows)
        data, experience = await self._episode(task, 0, snapshot)
        items = []
        for entry in await snapshot.embed(experience):
            kept = snapshot.add_embedded(entry)
            items.append({**entry.model_dump(mode="json", exclude=set(EMBEDDING_FIELDS)), "kept": bool(kept)})
        data["experience"] = items
        return data

    async def _rebuild(self, records: list[dict[str, Any]]) -> None:
        """Fallback: the initial memory plus every recorded entry, re-embedded, in episode order."""
        assert self.make_memory is not None
        self.memory = self.make_memory()
        for rec in records:
            items = rec.get("experience") or []
            entries = [self.memory.entry_from_record({k: v for k, v in it.items() if k != "kept"}) for it in items]
            entries = await self.memory.embed(entries)
            for entry, item in zip(entries, items, strict=True):
                kept = self.memory.add_embedded(entry)
                if bool(item.get("kept")) != kept:
                    log.warning("stream %s: rebuilding episode %s gave a different dedup decision for %s",
                                self.spec.stream_id, rec.get("index"), entry.id)
            self.memory.commit(rec["index"])

    # -- committing ---------------------------------------------------------------------------------

    async def _commit(self, data: dict[str, Any], experience: list[Any], index: int) -> None:
        """Embed and add an episode's experience in order; the record keeps each entry without its
        vectors plus the commit decision."""
        items: list[dict[str, Any]] = []
        if self.memory is not None:
            for entry in await self.memory.embed(experience):
                kept = self.memory.add_embedded(entry)
                items.append({**entry.model_dump(mode="json", exclude=set(EMBEDDING_FIELDS)), "kept": bool(kept)})
            self.memory.commit(index)
        data["experience"] = items

    # -- running ------------------------------------------------------------------------------------

    def _env(self, slot: int) -> Any:
        """The env of a wave slot, made once: inline, or in a worker process / Ray actor of its own."""
        from worldmind_local.envworkers import make_env_worker

        while len(self._envs) <= slot:
            self._envs.append(make_env_worker(self.adapter, self.env_kind, self.env_workers,
                                              label=f"{self.spec.stream_id}/{len(self._envs)}"))
        return self._envs[slot]

    async def _episode(self, task: Task, slot: int, memory_view: Any) -> tuple[dict[str, Any], list[Any]]:
        from worldmind_local.agent.driver import run_episode

        ctx = self.make_context(memory_view)
        outcome = await run_episode(self.method, task, self._env(slot), ctx)
        data = outcome.record.model_dump(mode="json")
        data.setdefault("index", task.index)
        data["stream_id"] = self.spec.stream_id
        return data, outcome.experience

    async def _save_memory(self) -> None:
        if self.memory is not None:
            await asyncio.to_thread(self.memory.save, self.dir.memory_path)

    async def run(self) -> StreamOutcome:
        t0 = time.perf_counter()
        self.dir.ensure()
        outcome = StreamOutcome(self.spec.stream_id, self.spec, status="failed")
        try:
            # Built here, not by the caller: a stream whose memory cannot load fails alone.
            self.memory = self.make_memory() if self.make_memory else None
            self.initial_rows = len(self.memory) if self.memory is not None else 0
            records = await self.restore()
            outcome.records = records
            if self.memory is not None:
                await self._save_memory()
            if self.gaps:
                log.warning("stream %s: re-running %d episode(s) whose records were quarantined: %s",
                            self.spec.stream_id, len(self.gaps), [t.index for t in self.gaps])
                order = {t.index: i for i, t in enumerate(self.tasks)}
                for task in self.gaps:
                    records.append(await self._rerun_gap(task))
                    outcome.ran_episodes += 1
                records.sort(key=lambda r: order[r["index"]])
                self.dir.rewrite_episodes(records)
            self.dir.write_status("running", done=len(records), total=len(self.tasks))
            done = {r["index"] for r in records}
            pending = [t for t in self.tasks if t.index not in done]
            for start in range(0, len(pending), self.wave):
                batch = pending[start: start + self.wave]
                views = [self.memory.copy() if self.memory is not None and self.wave > 1 else self.memory
                         for _ in batch]
                results = list(await asyncio.gather(
                    *(self._episode(task, slot, views[slot]) for slot, task in enumerate(batch))))
                for (data, experience), task in zip(results, batch, strict=True):
                    await self._commit(data, experience, task.index)
                    if self.wave > 1:
                        data["wave"] = [batch[0].index, len(batch)]
                await self._save_memory()
                self.dir.append_episodes([data for data, _ in results])
                for data, _ in results:
                    records.append(data)
                    outcome.ran_episodes += 1
                    if self.on_episode:
                        self.on_episode(self.spec, data)
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
            from worldmind_local.envworkers import close_env

            for env in self._envs:
                await close_env(env)  # a worker's simulator shuts down; the loop keeps turning meanwhile
            outcome.seconds = time.perf_counter() - t0
        return outcome
