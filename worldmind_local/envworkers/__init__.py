"""Environments off the event loop: each stream's env in its own worker process or Ray actor.

A twin steps in microseconds, so it runs inline on the runner's event loop. A real simulator
(AI2-THOR, habitat-sim) blocks for 0.1-2 s per step and crashes now and then; inline, one step stalls
every stream and one crash ends the run. `make_env_worker` gives a stream an env of the kind asked for:

- `inline`: the adapter's env itself (default for the twins);
- `process`: a `WorkerEnv` whose env lives in a spawned process (default for `--env embodiedbench`),
  started with the benchmark's display / GPU setup and awaited through its pipe;
- `ray`: the same worker as a Ray actor with resource requests, on a local or remote cluster
  (Ray is an optional extra, imported only here, only then).

The driver awaits `areset`/`astep` where an env has them. Observations cross as plain data, field by
field and only once read (`_codec.py`). A worker that dies or hangs is restarted; the episode is
replayed to where it was or recorded as an error, per `WorkerSettings.failure` (`_proxy.py`).
"""

from worldmind_local.envworkers._base import (
    DEFAULT_TIMEOUTS,
    EnvSpec,
    EnvWorkerError,
    FailurePolicy,
    WorkerKind,
    WorkerSettings,
    resolve_kind,
    worker_env_vars,
)
from worldmind_local.envworkers._proxy import RemoteObservation, WorkerEnv, close_env, make_env_worker
from worldmind_local.envworkers._wrappers import EnvWrapper, InjectFault, StepLatency

__all__ = [
    "DEFAULT_TIMEOUTS",
    "EnvSpec",
    "EnvWorkerError",
    "EnvWrapper",
    "FailurePolicy",
    "InjectFault",
    "RemoteObservation",
    "StepLatency",
    "WorkerEnv",
    "WorkerKind",
    "WorkerSettings",
    "close_env",
    "make_env_worker",
    "resolve_kind",
    "worker_env_vars",
]
