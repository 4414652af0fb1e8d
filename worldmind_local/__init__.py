"""WorldMind-Local: the WorldMind method and its harness, on local models.

Importing this package imports no model library and no simulator.
"""

from worldmind_local.env import BenchmarkAdapter, Env, Observation, StepResult, Task, TaskDataError
from worldmind_local.registry import BACKENDS, BENCHMARKS, METHODS

__all__ = [
    "BACKENDS",
    "BENCHMARKS",
    "METHODS",
    "BenchmarkAdapter",
    "Env",
    "Observation",
    "StepResult",
    "Task",
    "TaskDataError",
]
__version__ = "0.1.0"
