"""Where EmbodiedBench task data lives, which task suite a command runs on, and the strict readers
every benchmark's loader uses for it.

Data files are input we do not control: `read_json_file`, `finite_number` and `data_file` turn a
non-UTF-8 byte, a broken or absurdly nested JSON file, a NaN / infinite / float-overflowing position,
or a record field used as a file name that points outside the data folder into one `TaskDataError`
naming the file, the record and the field, instead of a traceback far away from the cause.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from worldmind_local.env import BenchmarkAdapter, Task, TaskDataError
from worldmind_local.registry import BENCHMARKS

__all__ = [
    "default_data_dir", "resolve_data_dir", "Suite", "load_suite", "adapter", "read_json_file",
    "finite_number", "data_file",
]

DATA_ENV_VAR = "WORLDMIND_DATA"


def default_data_dir() -> Path:
    """`$WORLDMIND_DATA`, then `~/.cache/worldmind/embodiedbench`."""
    env = os.environ.get(DATA_ENV_VAR)
    if env:
        return Path(env).expanduser()
    return Path.home() / ".cache" / "worldmind" / "embodiedbench"


def resolve_data_dir(data_dir: str | Path | None) -> Path:
    return Path(data_dir).expanduser() if data_dir else default_data_dir()


# More digits than any float can hold: the value becomes inf, which `finite_number` then refuses with
# the field named (int() would raise a ValueError naming nothing past 4,300 digits).
_MAX_INT_DIGITS = 310
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,199}")


def _lenient_int(digits: str) -> int | float:
    return float("inf") if len(digits.lstrip("-")) > _MAX_INT_DIGITS else int(digits)


# NaN / Infinity / 1e999 decode to non-finite floats on purpose: the validators then name the field.
_DECODER = json.JSONDecoder(parse_int=_lenient_int)


def read_json_file(path: Path) -> Any:
    """A data file as JSON: UTF-8 only; any problem is a TaskDataError naming the file and the line.

    FileNotFoundError passes through (callers say which file the pack should have).
    """
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise TaskDataError(path, "<file>", f"cannot be read ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise TaskDataError(path, f"<line {line}>", f"not UTF-8 text (byte {exc.start}: {exc.reason})") from None
    try:
        return _DECODER.decode(text)
    except json.JSONDecodeError as exc:
        raise TaskDataError(path, f"<line {exc.lineno}>", f"not valid JSON (column {exc.colno}: {exc.msg})") from None
    except RecursionError:
        raise TaskDataError(path, "<file>", "JSON nested too deeply") from None
    except ValueError as exc:
        raise TaskDataError(path, "<file>", f"not valid JSON ({exc})") from None


def finite_number(path: Path | str, field_name: str, value: Any) -> float:
    """`value` as a float when it is a real, finite number (not a bool, NaN, inf or beyond float range)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TaskDataError(path, field_name, f"expected a finite number, got {_short(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise TaskDataError(path, field_name, f"expected a finite number, got {_short(value)}")
    return number


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({len(text)} characters)"


def data_file(folder: Path, name: Any, suffix: str, where: Path | str, field_name: str) -> Path:
    """`folder/<name><suffix>` for a file name taken from a record, refused unless `name` is one plain
    name (letters, digits, `_.-`; no separator, no `..`, not absolute) and the path, symlinks resolved,
    stays inside `folder`: a data file can never make us open anything outside the data pack."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise TaskDataError(where, field_name, f"{_short(name)} is not a plain file name inside the data pack")
    path = Path(folder) / f"{name}{suffix}"
    if not path.resolve().is_relative_to(Path(folder).resolve()):
        raise TaskDataError(where, field_name, f"{name!r} resolves outside {folder}")
    return path


def adapter(benchmark: str) -> BenchmarkAdapter:
    return BENCHMARKS.get(benchmark)


@dataclass(frozen=True)
class Suite:
    """A task suite: EmbodiedBench's own episodes (from a data dir) or a generated one (from a seed)."""

    benchmark: str
    kind: str  # "embodiedbench" | "generated"
    data_dir: Path | None = None
    seed: int = 0
    n_per_subset: int = 50

    def describe(self) -> str:
        if self.kind == "generated":
            return f"{self.benchmark} generated suite (seed {self.seed}, {self.n_per_subset} per subset)"
        return f"{self.benchmark} EmbodiedBench tasks from {self.data_dir}"

    def tasks(self, subset: str) -> list[Task]:
        ad = adapter(self.benchmark)
        if subset not in ad.subsets:
            raise ValueError(
                f"unknown subset {subset!r} for {self.benchmark}; known: {', '.join(ad.subsets)}"
            )
        if self.kind == "generated":
            return ad.generate_tasks(self.seed, subset, self.n_per_subset)
        assert self.data_dir is not None
        return ad.load_tasks(self.data_dir, subset)


def load_suite(
    benchmark: str,
    *,
    data_dir: str | Path | None = None,
    suite: str | None = None,
    seed: int = 0,
    n_per_subset: int = 50,
) -> Suite:
    """Pick the suite. `suite=None` means: EmbodiedBench data if it is present, else the generated one.

    An explicit `--data-dir` that holds no data for the benchmark is an error (never a silent fallback).
    """
    ad = adapter(benchmark)
    if suite not in (None, "embodiedbench", "generated"):
        raise ValueError(f"unknown suite {suite!r}; use 'embodiedbench' or 'generated'")
    if suite == "generated":
        return Suite(benchmark, "generated", seed=seed, n_per_subset=n_per_subset)
    path = resolve_data_dir(data_dir)
    if ad.has_data(path):
        return Suite(benchmark, "embodiedbench", data_dir=path)
    if suite == "embodiedbench" or data_dir is not None:
        raise FileNotFoundError(
            f"no {benchmark} data under {path} (expected the layout of EmbodiedBench's data pack, "
            f"e.g. {path / benchmark}); pass --data-dir DIR or --suite generated"
        )
    return Suite(benchmark, "generated", seed=seed, n_per_subset=n_per_subset)
