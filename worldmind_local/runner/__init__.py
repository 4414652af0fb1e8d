"""The batch runner: many experiment streams on shared backends, resumable run folders."""

from worldmind_local.runner.config import RunConfig, StreamSpec, expand_streams, load_plan_file
from worldmind_local.runner.run import RunResult, run_experiment

__all__ = [
    "RunConfig",
    "RunResult",
    "StreamSpec",
    "expand_streams",
    "load_plan_file",
    "run_experiment",
]
