"""Checks made before a run folder is created, so a mistyped command fails in one line, at once.

A typo in a model spec, an `--out` that is a file, or a `--memory-from` that is not a repository would
otherwise surface minutes later (after models load) or halfway through a run. Each function is pure
apart from reading the file system and the model spec files, loads no weights, and raises ValueError
(or FileNotFoundError) with one line that says what is wrong and what would be right.
"""

from __future__ import annotations

import difflib
import os
from pathlib import Path
from typing import Any

__all__ = ["check_out_path", "check_model_specs", "check_memory_source"]

def check_out_path(out: str | Path) -> Path:
    """The run folder can be created (or is an existing, writable folder). Returns it."""
    path = Path(out).expanduser()
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {path} is an existing file, not a run folder; choose another --out")
    existing = path
    while not existing.exists():
        if existing.parent == existing:
            break
        existing = existing.parent
    if existing.exists() and not existing.is_dir():
        raise ValueError(f"--out {path}: {existing} is a file, so the run folder cannot be created under it")
    if existing.exists() and not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"--out {path}: {existing} is not writable by this user")
    return path


def _known_addresses() -> list[str]:
    from models.specs import list_specs

    return [spec.address for spec in list_specs()]


def _suggest(address: str, known: list[str]) -> str:
    """Close matches by the whole address and by the name alone (a wrong backend prefix)."""
    close = difflib.get_close_matches(address, known, n=3, cutoff=0.6)
    names = difflib.get_close_matches(address.partition(":")[2] or address,
                                      [k.partition(":")[2] for k in known], n=3, cutoff=0.6)
    close += [k for k in known if k.partition(":")[2] in names]
    close = list(dict.fromkeys(close))[:4]
    return f"; did you mean {', '.join(close)}?" if close else ""


def _check_one(address: str, known: list[str]) -> Any:
    from models.specs import load_spec

    if address == "replay":
        return None  # the cache's only model: checked when the cache is opened
    if address.startswith("replay:"):
        target = address.partition(":")[2]
        if ":" not in target or target.partition(":")[0] not in {k.partition(":")[0] for k in known}:
            return None  # a raw model id recorded in the cache
        address = target
    try:
        return load_spec(address)
    except KeyError:
        raise ValueError(
            f"unknown model spec {address!r}{_suggest(address, known)} "
            "(`worldmind models list` shows every spec; a spec is backend:name or a .yaml file)"
        ) from None
    except ValueError as exc:  # a broken spec file
        raise ValueError(" ".join(str(exc).split())) from None


def check_model_specs(addresses: list[str]) -> dict[str, Any]:
    """Each address resolves to a model spec (read from the YAML files only; no weights are loaded).

    `replay`, `replay:<model id>` and `replay:<spec address>` are accepted (the spec, when one is named,
    must exist). Returns address -> ModelSpec (None for replay of a raw model id)."""
    known = _known_addresses()
    return {address: _check_one(address, known) for address in dict.fromkeys(addresses)}


def check_memory_source(path: str | Path) -> Path:
    """`--memory-from` names something a memory can be read from: a run folder with one stream, a stream's
    `memory/`, an export, parquet, or `hub:OWNER/NAME[@REV]` in the local Hub cache. Returns where it
    resolved to. Reads names and markers only; the content is checked when the stream loads it."""
    from worldmind_local.memory.sources import locate

    return locate(str(path))[1]
