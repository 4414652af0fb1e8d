"""Ray workers: the same `EnvHost`, as a Ray actor with resource requests, anywhere on a cluster.

Ray is an optional extra (`pip install 'worldmind-local[ray]'`); it is imported here, on first use,
and nowhere else. `ray_address` None joins `RAY_ADDRESS` if set, else starts a local cluster on this
machine. An actor asks for `ray_num_cpus` CPUs, `ray_num_gpus` GPUs (a fraction packs several
simulators on one GPU; Ray sets the actor's CUDA_VISIBLE_DEVICES) and any custom resources the nodes
advertise (`ray_resources`, e.g. `display:1` on nodes started with `--resources '{"display": 4}'`).
Every node needs this package installed (or a `runtime_env` that ships it).
"""

from __future__ import annotations

import asyncio
import threading
from typing import Any

from worldmind_local.envworkers._base import EnvSpec, WorkerLost, WorkerSettings

__all__ = ["RayTransport", "ray_resources_for"]

# Per actor when the settings do not say: a twin is microseconds of CPU per step, so eight share a core;
# a real simulator is a whole process with a renderer (habitat-sim and CloudRendering on a GPU).
_DEFAULT_CPUS = {"twin": 0.125, "embodiedbench": 1.0}
_DEFAULT_GPUS = {"eb_alfred": 0.0, "eb_habitat": 0.25, "eb_navigation": 0.25}

_lock = threading.Lock()
_actor_class: Any = None


def _ray(address: str | None) -> Any:
    """`ray`, initialised once per process."""
    try:
        import ray
    except ImportError as exc:
        raise ImportError("--env-workers ray needs Ray: pip install 'worldmind-local[ray]' "
                          "(or `make venv-ray`)") from exc
    with _lock:
        if not ray.is_initialized():
            ray.init(address=address, namespace="worldmind", include_dashboard=False, log_to_driver=False,
                     ignore_reinit_error=True)
    return ray


def _host_actor(ray: Any) -> Any:
    global _actor_class
    with _lock:
        if _actor_class is None:
            from worldmind_local.envworkers._host import EnvHost

            _actor_class = ray.remote(max_restarts=0, max_task_retries=0)(EnvHost)
    return _actor_class


def ray_resources_for(spec: EnvSpec, settings: WorkerSettings) -> dict[str, Any]:
    """The actor's resource request."""
    cpus = settings.ray_num_cpus if settings.ray_num_cpus is not None else _DEFAULT_CPUS.get(spec.kind, 1.0)
    gpus = settings.ray_num_gpus
    if gpus is None:
        gpus = _DEFAULT_GPUS.get(spec.benchmark, 0.0) if spec.kind == "embodiedbench" else 0.0
    request: dict[str, Any] = {"num_cpus": cpus, "num_gpus": gpus}
    if settings.ray_resources:
        request["resources"] = dict(settings.ray_resources)
    return request


class RayTransport:
    """One `EnvHost` actor. Same contract as `ProcessTransport`."""

    def __init__(self, spec: EnvSpec, env_vars: dict[str, str], settings: WorkerSettings, *,
                 name: str = "envworker") -> None:
        self._ray = _ray(settings.ray_address)
        options: dict[str, Any] = ray_resources_for(spec, settings)
        if env_vars:
            options["runtime_env"] = {"env_vars": dict(env_vars)}
        self._actor = _host_actor(self._ray).options(**options).remote(spec, settings.frame_codec)
        self.name = name
        self._pid: int | None = None

    @property
    def pid(self) -> int | None:
        return self._pid

    def _translate(self, exc: BaseException, what: str) -> BaseException:
        errors = self._ray.exceptions
        if isinstance(exc, errors.RayActorError | errors.ObjectLostError | errors.WorkerCrashedError):
            return WorkerLost(f"worker {self.name} (Ray actor, pid {self._pid}) died during {what}: "
                              f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}")
        if isinstance(exc, errors.RayTaskError):  # the env raised: hand over its own exception
            cause = getattr(exc, "cause", None)
            return cause if isinstance(cause, BaseException) else exc
        return exc

    async def _await(self, ref: Any, timeout: float, what: str) -> Any:
        try:
            return await asyncio.wait_for(asyncio.wrap_future(ref.future()), timeout)
        except asyncio.TimeoutError:
            raise WorkerLost(f"worker {self.name} (Ray actor, pid {self._pid}) gave no answer to {what} "
                             f"within {timeout:g} s (hung, or no node has the resources asked for)") from None
        except Exception as exc:
            raise self._translate(exc, what) from None

    async def hello(self, timeout: float) -> dict[str, Any]:
        hello = await self._await(self._actor.hello.remote(), timeout, "start")
        self._pid = hello.get("pid")
        return hello

    async def call(self, op: str, args: tuple[Any, ...], timeout: float) -> Any:
        return await self._await(getattr(self._actor, op).remote(*args), timeout, op)

    def call_sync(self, op: str, args: tuple[Any, ...], timeout: float) -> Any:
        ref = getattr(self._actor, op).remote(*args)
        try:
            return self._ray.get(ref, timeout=timeout)
        except self._ray.exceptions.GetTimeoutError:
            raise WorkerLost(f"worker {self.name} gave no answer to {op} within {timeout:g} s") from None
        except Exception as exc:
            raise self._translate(exc, op) from None

    def kill(self) -> None:
        try:
            self._ray.kill(self._actor, no_restart=True)
        except Exception:  # already gone
            pass

    async def aclose(self, timeout: float = 30.0) -> None:
        try:
            await asyncio.wait_for(asyncio.wrap_future(self._actor.close.remote().future()), timeout)
        except Exception:  # dead or hung: the kill below is what matters
            pass
        finally:  # also when cancelled (Ctrl-C during shutdown)
            self.kill()

    def close(self, timeout: float = 30.0) -> None:
        try:
            self._ray.get(self._actor.close.remote(), timeout=timeout)
        except Exception:
            pass
        self.kill()
