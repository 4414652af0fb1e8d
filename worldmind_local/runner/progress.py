"""A progress bar per stream (tqdm on a terminal; one plain line per finished episode otherwise)."""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["Progress"]


class _Bar:
    def __init__(self, owner: Progress, name: str, total: int, position: int) -> None:
        self.owner = owner
        self.name = name
        self.total = total
        self.done = 0
        self.successes = 0
        self._tqdm = None
        if owner.tty:
            from tqdm import tqdm

            self._tqdm = tqdm(total=total, desc=name[-48:], position=position, leave=True,
                              dynamic_ncols=True, unit="ep")

    def skip(self, n: int) -> None:
        """Episodes already on disk (resume)."""
        self.done += n
        if self._tqdm is not None and n:
            self._tqdm.update(n)

    def update(self, record: dict[str, Any]) -> None:
        self.done += 1
        self.successes += bool(record.get("success"))
        if self._tqdm is not None:
            self._tqdm.update(1)
            self._tqdm.set_postfix(sr=f"{self.successes}/{self.done}")
        elif self.owner.enabled is not False:
            print(f"[{self.name}] episode {record.get('index')} "
                  f"{'success' if record.get('success') else record.get('taxonomy', 'fail')} "
                  f"progress={float(record.get('progress') or 0):.2f} ({self.done}/{self.total})",
                  file=sys.stderr, flush=True)

    def close(self) -> None:
        if self._tqdm is not None:
            self._tqdm.close()


class Progress:
    def __init__(self, enabled: bool | None = None) -> None:
        self.enabled = enabled
        self.tty = bool(enabled) or (enabled is None and sys.stderr.isatty())
        self.bars: list[_Bar] = []

    def add(self, name: str, total: int) -> _Bar:
        bar = _Bar(self, name, total, len(self.bars))
        self.bars.append(bar)
        return bar

    def close(self) -> None:
        for bar in self.bars:
            bar.close()
