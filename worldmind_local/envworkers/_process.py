"""Process workers: one spawned process per env, one pipe to it, awaited on the event loop.

`spawn` (or `forkserver`), never `fork`: the runner holds torch, an engine and threads, and a forked
copy of those is unsafe; a spawned worker imports only the benchmark it steps. The runner waits on the
pipe and on the process sentinel with `loop.add_reader`, so hundreds of workers cost no threads, a
death is seen at once (EOF or sentinel), and a hang is a timeout. The worker ignores SIGINT (the runner
closes it on Ctrl-C) and exits when its pipe closes (the runner is gone).
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import pickle
import signal
import time
import traceback
from multiprocessing.connection import Connection
from typing import Any

from worldmind_local.envworkers._base import EnvSpec, WorkerLost

__all__ = ["ProcessTransport"]


def _exception(exc: BaseException) -> BaseException:
    """The env's exception as it can cross the pipe, with the worker's traceback in its notes."""
    text = "".join(traceback.format_exception(exc))
    try:
        add_note = getattr(exc, "add_note", None)  # Python >= 3.11
        if add_note is not None:
            add_note("in the env worker:\n" + text)
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:
        return RuntimeError(f"{type(exc).__name__}: {exc}\nin the env worker:\n{text}")


def _settle(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


def _exit_on_term(signum: int, frame: Any) -> None:
    raise SystemExit(128 + signum)


def _serve(conn: Connection, spec: EnvSpec, env_vars: dict[str, str], codec: str) -> None:
    """The worker's main loop (runs in the spawned process). Its own session, so the runner can kill
    it together with whatever the simulator started (a Unity player), and Ctrl-C in the terminal reaches
    only the runner, which closes the workers in order; SIGTERM still runs the env's close."""
    os.setsid()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit_on_term)
    os.environ.update(env_vars)
    from worldmind_local.envworkers._host import EnvHost

    try:
        host = EnvHost(spec, codec)
        conn.send(("ok", host.hello()))
    except BaseException as exc:
        conn.send(("err", _exception(exc)))
        return
    try:
        while True:
            try:
                op, args = conn.recv()
            except (EOFError, OSError):  # the runner is gone
                break
            if op == "close":
                break
            try:
                reply: tuple[str, Any] = ("ok", getattr(host, op)(*args))
            except Exception as exc:
                reply = ("err", _exception(exc))
            conn.send(reply)
    finally:
        host.close()


class ProcessTransport:
    """One worker process and its pipe. `call` raises the env's own exceptions as they are, and
    `WorkerLost` when the process died or did not answer in time."""

    def __init__(self, spec: EnvSpec, env_vars: dict[str, str], *, start_method: str = "spawn",
                 codec: str = "array", name: str = "envworker") -> None:
        ctx = mp.get_context(start_method)
        self._conn, child = ctx.Pipe(duplex=True)
        self._proc = ctx.Process(target=_serve, args=(child, spec, env_vars, codec), name=name, daemon=True)
        self._proc.start()
        child.close()  # only the worker holds its end: its death is EOF here
        self.name = name
        self._loop: asyncio.AbstractEventLoop | None = None
        self._waiter: asyncio.Future[None] | None = None

    @property
    def pid(self) -> int | None:
        return self._proc.pid

    def _lost(self, what: str) -> WorkerLost:
        self._proc.join(0.5)
        code = self._proc.exitcode
        how = (f"killed by signal {-code}" if code is not None and code < 0 else
               f"exited with code {code}" if code is not None else "still running")
        return WorkerLost(f"worker {self.name} (pid {self.pid}) {what} ({how})")

    def _unwrap(self, message: tuple[str, Any]) -> Any:
        status, value = message
        if status == "err":
            raise value
        return value

    def _arm(self) -> asyncio.Future[None]:
        """A future set when the pipe or the sentinel is readable. The readers stay registered between
        calls (add/remove per call costs two epoll syscalls each) and drop themselves when nobody waits,
        so a readable fd with no waiter (EOF after a death) cannot spin the loop."""
        loop = asyncio.get_running_loop()
        if self._loop is not loop:
            self._disarm()
            for fd in (self._conn.fileno(), self._proc.sentinel):
                loop.add_reader(fd, self._wake)
            self._loop = loop
        self._waiter = loop.create_future()
        return self._waiter

    def _wake(self) -> None:
        waiter = self._waiter
        if waiter is None or waiter.done():
            self._disarm()
        else:
            waiter.set_result(None)

    def _disarm(self) -> None:
        loop, self._loop = self._loop, None
        if loop is not None and not loop.is_closed():
            for fd in (self._conn.fileno(), self._proc.sentinel):
                loop.remove_reader(fd)

    async def _recv(self, timeout: float, what: str) -> Any:
        """The next reply. A wake-up may be stale (a readiness event queued before the last reply was
        read), so the pipe is checked again after each one."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while not self._conn.poll(0) and self._proc.is_alive():
            remaining = deadline - loop.time()
            if remaining <= 0:
                raise WorkerLost(f"worker {self.name} (pid {self.pid}) gave no answer to {what} within "
                                 f"{timeout:g} s (hung)")
            ready = self._arm()
            timer = loop.call_later(remaining, _settle, ready)
            try:
                await ready
            finally:
                timer.cancel()
                self._waiter = None
        return self._read(what)

    def _read(self, what: str) -> Any:
        try:
            if not self._conn.poll(0):  # the sentinel fired, the pipe is empty: it died
                raise self._lost(f"died during {what}")
            return self._unwrap(self._conn.recv())
        except (EOFError, OSError, pickle.UnpicklingError):
            raise self._lost(f"died during {what}") from None

    def _send(self, op: str, args: tuple[Any, ...]) -> None:
        try:
            self._conn.send((op, args))
        except (BrokenPipeError, EOFError, OSError):
            raise self._lost(f"died before {op}") from None

    async def hello(self, timeout: float) -> dict[str, Any]:
        return await self._recv(timeout, "start")

    async def call(self, op: str, args: tuple[Any, ...], timeout: float) -> Any:
        self._send(op, args)
        return await self._recv(timeout, op)

    def call_sync(self, op: str, args: tuple[Any, ...], timeout: float) -> Any:
        """Blocking, for the lazy fields an Observation reads synchronously (short, rare calls)."""
        self._send(op, args)
        try:
            ready = self._conn.poll(timeout)
        except (EOFError, OSError):
            raise self._lost(f"died during {op}") from None
        if not ready:
            raise WorkerLost(f"worker {self.name} (pid {self.pid}) gave no answer to {op} within {timeout:g} s")
        return self._read(op)

    def kill(self) -> None:
        """SIGKILL to the worker's whole process group (the simulator's own processes too)."""
        if not self._conn.closed:
            self._disarm()
        if self._proc.pid is not None:
            try:
                os.killpg(self._proc.pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):  # not yet in its own group, or already gone
                if self._proc.is_alive():
                    self._proc.kill()
        self._proc.join(5)
        self._conn.close()

    async def aclose(self, timeout: float = 30.0) -> None:
        """Ask the worker to close its env (a simulator shuts its player down), wait for it to exit while
        discarding any late reply (a worker blocked sending one would never read the request), then
        kill its process group, also when this is cancelled (Ctrl-C during shutdown)."""
        try:
            if self._proc.is_alive() and not self._conn.closed:
                self._disarm()
                self._conn.send(("close", ()))
                loop = asyncio.get_running_loop()
                gone: asyncio.Future[None] = loop.create_future()
                loop.add_reader(self._proc.sentinel, _settle, gone)
                loop.add_reader(self._conn.fileno(), self._drain)
                try:
                    await asyncio.wait_for(gone, timeout)
                except asyncio.TimeoutError:
                    pass
                finally:
                    loop.remove_reader(self._proc.sentinel)
                    loop.remove_reader(self._conn.fileno())
        except OSError:
            pass
        finally:
            self.kill()

    def _drain(self) -> None:
        try:
            while self._conn.poll(0):
                self._conn.recv()
        except (EOFError, OSError, pickle.UnpicklingError):
            asyncio.get_running_loop().remove_reader(self._conn.fileno())

    def close(self, timeout: float = 30.0) -> None:
        """Blocking form of `aclose`."""
        try:
            if self._proc.is_alive() and not self._conn.closed:
                self._disarm()
                self._conn.send(("close", ()))
                deadline = time.monotonic() + timeout
                while self._proc.is_alive() and time.monotonic() < deadline:
                    if self._conn.poll(0.05):
                        self._conn.recv()
        except (EOFError, OSError, pickle.UnpicklingError):
            pass
        finally:
            self.kill()
