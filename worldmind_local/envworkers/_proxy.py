"""The runner's side of a worker: an Env whose `areset`/`astep` are awaited without blocking the loop.

Failure policy (`WorkerSettings.failure`):

- `replay` (default): a worker that dies or hangs is killed and restarted; the new one resets the
  episode's task and replays the actions already taken, checking that every replayed step gives the
  same feedback, success, progress and end as the first time; then the failed call runs again. The
  episode goes on as if nothing happened (the simulators are deterministic given the task and the
  actions: that is what EmbodiedBench's evaluation relies on). At most `max_restarts` restarts per
  call; a replay that diverges, or restarts used up, raise `EnvWorkerError`.
- `error`: the worker is killed, `EnvWorkerError` is raised at once (the episode is recorded as an
  error with the reason), and the next episode starts a fresh worker.

Either way the other streams go on, and the runner writes nothing until an episode has finished.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
from typing import Any

from worldmind_local.env import Observation, StepResult, Task, UnknownActionError
from worldmind_local.envworkers._base import (
    EnvSpec,
    EnvWorkerError,
    WorkerLost,
    WorkerSettings,
    resolve_kind,
    worker_env_vars,
)
from worldmind_local.envworkers._codec import FIELDS, decode_field, step_digest

__all__ = ["WorkerEnv", "RemoteObservation", "make_env_worker", "close_env"]

log = logging.getLogger("worldmind_local.envworkers")
_numbers = itertools.count()


class RemoteObservation(Observation):
    """An Observation whose fields live in the worker until read. `text` and `state` use the base
    class's lazy functions; `image` is a lazy property (as the navigation twin's)."""

    __slots__ = ("_image", "_image_fn")

    def __init__(self, fields: dict[str, Any], fetch: Any) -> None:
        def lazy(name: str) -> Any:
            return decode_field(name, fields[name]) if name in fields else (lambda: fetch(name))

        super().__init__(lazy("text"), state=lazy("state"))
        self._image_fn = None if "image" in fields else (lambda: fetch("image"))
        self._image = decode_field("image", fields["image"]) if "image" in fields else None

    @property  # type: ignore[override]
    def image(self) -> Any:
        if self._image_fn is not None:
            self._image, self._image_fn = self._image_fn(), None
        return self._image

    @image.setter
    def image(self, value: Any) -> None:
        self._image, self._image_fn = value, None


class WorkerEnv:
    """An Env living in a worker (process or Ray actor), started at the first reset."""

    def __init__(self, spec: EnvSpec, settings: WorkerSettings, kind: str, *, label: str = "") -> None:
        self.spec, self.settings, self.kind = spec, settings, kind
        self.benchmark = spec.benchmark
        self.index = next(_numbers)  # spreads workers over displays / GPUs, kept across restarts
        self.name = f"{kind}:{label or spec.benchmark}#{self.index}"
        self.step_timeout, self.reset_timeout = settings.timeouts(spec.benchmark)
        self.actions: list[str] = []
        self.max_steps = 0
        self.max_invalid: int | None = None
        self.restarts = 0
        self._transport: Any = None
        self._eager = set(settings.eager)
        self._task: Task | None = None
        self._history: list[tuple[int, tuple[Any, ...]]] = []
        self._epoch = 0
        self._replay_needed = False

    # -- the worker ---------------------------------------------------------------------------------

    @property
    def pid(self) -> int | None:
        return self._transport.pid if self._transport is not None else None

    def _new_transport(self) -> Any:
        env_vars = worker_env_vars(self.spec, self.index, self.settings, ray=self.kind == "ray")
        if self.kind == "ray":
            from worldmind_local.envworkers._ray import RayTransport

            return RayTransport(self.spec, env_vars, self.settings, name=self.name)
        from worldmind_local.envworkers._process import ProcessTransport

        return ProcessTransport(self.spec, env_vars, start_method=self.settings.start_method,
                                codec=self.settings.frame_codec, name=self.name)

    async def _start(self) -> None:
        transport = self._new_transport()
        self._transport = transport
        hello = await transport.hello(self.settings.start_timeout)
        self.max_steps, self.max_invalid = hello["max_steps"], hello["max_invalid"]

    def _discard(self) -> None:
        if self._transport is not None:
            self._transport.kill()
            self._transport = None
        self._replay_needed = self._task is not None

    async def _ready(self) -> None:
        """A live worker positioned where the episode is: started, and replayed after a restart."""
        if self._transport is None:
            await self._start()
        if self._replay_needed:
            await self._replay()

    async def _replay(self) -> None:
        assert self._task is not None
        reply = await self._transport.call("reset", (self._task, ()), self.reset_timeout)
        if reply["actions"] != self.actions:
            raise EnvWorkerError(f"{self.name}: replay of {self._task.id} gave a different action list")
        for n, (action_id, digest) in enumerate(self._history, start=1):
            step = await self._transport.call("step", (action_id, ()), self.step_timeout)
            if step_digest(step) != digest:
                raise EnvWorkerError(
                    f"{self.name}: replay of {self._task.id} diverged at step {n} (action {action_id}): "
                    f"{step_digest(step)} != {digest}; the simulator is not deterministic here")
        self._replay_needed = False
        log.warning("%s: restarted and replayed %d step(s) of %s", self.name, len(self._history), self._task.id)

    async def _call(self, op: str, args: tuple[Any, ...], timeout: float) -> Any:
        """One call, with the failure policy around it."""
        failures = 0
        while True:
            try:
                await self._ready()
                return await self._transport.call(op, args, timeout)
            except WorkerLost as lost:
                self._discard()
                failures += 1
                where = f" in {self._task.id}" if self._task is not None else ""
                if self.settings.failure == "error" or failures > self.settings.max_restarts:
                    self._replay_needed = False  # the episode is over; the next reset starts afresh
                    raise EnvWorkerError(f"{self.name}: {op}{where} failed: {lost}") from None
                self.restarts += 1
                log.warning("%s: %s; restarting (%d of %d) and replaying", self.name, lost, failures,
                            self.settings.max_restarts)

    async def start(self) -> None:
        """Start the worker now rather than at the first reset (benchmarks, or to fail early)."""
        await self._ready()

    # -- the Env seam -------------------------------------------------------------------------------

    async def areset(self, task: Task) -> Observation:
        self._task, self._history, self._replay_needed = None, [], False
        reply = await self._call("reset", (task, tuple(self._eager)), self.reset_timeout)
        self._task, self._epoch = task, self._epoch + 1
        self.actions = list(reply["actions"])
        self.max_steps, self.max_invalid = reply["max_steps"], reply["max_invalid"]
        return self._observation(reply["obs"])

    async def astep(self, action_id: int) -> StepResult:
        if self._task is None:
            raise RuntimeError(f"{self.name}: step before reset")
        reply = await self._call("step", (action_id, tuple(self._eager)), self.step_timeout)
        self._history.append((action_id, step_digest(reply)))
        return StepResult(
            feedback=reply["feedback"], success=reply["success"], progress=reply["progress"],
            invalid=reply["invalid"], done=reply["done"], observation=self._observation(reply["obs"]),
            end_reason=reply["end_reason"], info=reply["info"],
        )

    def _observation(self, payload: dict[str, Any]) -> RemoteObservation:
        number, epoch = payload["n"], self._epoch
        fields = {k: v for k, v in payload.items() if k in FIELDS}
        return RemoteObservation(fields, lambda name: self._fetch(epoch, number, name))

    def _fetch(self, epoch: int, number: int, name: str) -> Any:
        """A lazy field, read now (synchronously: Observation fields are plain attributes). Reading a
        field of a step's observation means the consumer reads it every step, so from then on it comes
        with every reply instead (one round trip saved per step). The reset's image is read once per
        episode by the driver to see whether the env renders any, which is no reason to ship them all."""
        if epoch != self._epoch:
            raise EnvWorkerError(f"{self.name}: {name} of an observation of an earlier episode")
        if self._transport is None or self._replay_needed:
            raise EnvWorkerError(f"{self.name}: the worker was lost before {name} of observation "
                                 f"{number} was read")
        try:
            value = self._transport.call_sync("fetch", (number, name), self.step_timeout)
        except WorkerLost as lost:
            self._discard()
            raise EnvWorkerError(f"{self.name}: fetching {name} failed: {lost}") from None
        if number > 0:
            self._eager.add(name)
        return decode_field(name, value)

    def action_id(self, name: str) -> int:
        try:
            return self.actions.index(name)
        except ValueError:
            task = self._task.id if self._task is not None else "no task"
            raise UnknownActionError(f"unknown action {name!r} for {task}") from None

    def reset(self, task: Task) -> Observation:
        """Blocking form (scripts, tests); the runner awaits `areset`."""
        return asyncio.run(self.areset(task))

    def step(self, action_id: int) -> StepResult:
        return asyncio.run(self.astep(action_id))

    async def aclose(self) -> None:
        if self._transport is not None:
            transport, self._transport = self._transport, None
            await transport.aclose()

    def close(self) -> None:
        if self._transport is not None:
            transport, self._transport = self._transport, None
            transport.close()


def make_env_worker(adapter: Any, env_kind: str, settings: WorkerSettings | None = None, *,
                    label: str = "", options: dict[str, Any] | None = None) -> Any:
    """The env a stream steps: the adapter's own env for `inline` (today's behaviour, no overhead),
    else a `WorkerEnv` whose worker builds the same env by the adapter's name."""
    settings = settings or WorkerSettings()
    kind = resolve_kind(settings.kind, env_kind)
    from worldmind_local.registry import BENCHMARKS

    registered = adapter.name in BENCHMARKS and BENCHMARKS.get(adapter.name) is adapter
    spec = EnvSpec(adapter.name, env_kind, dict(options or {}), tuple(settings.wrappers),
                   None if registered else adapter)
    if kind == "inline":
        return spec.build()
    return WorkerEnv(spec, settings, kind, label=label)


async def close_env(env: Any) -> None:
    """Close an env of either kind (`aclose` where it has one, so the loop keeps turning)."""
    aclose = getattr(env, "aclose", None)
    if aclose is not None:
        await aclose()
        return
    close = getattr(env, "close", None)
    if close is not None:
        close()
