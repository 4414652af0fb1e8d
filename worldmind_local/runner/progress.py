"""Progress of a run: one overall bar for all streams; per-stream detail only on request.

A paper table is dozens of streams, so one bar per stream scrolls the terminal away. By default the run
shows ONE bar: episodes done / total, the current throughput (tqdm's smoothed episodes per second) and
the ETA, plus how many streams are finished and the success count so far. Without a terminal it prints
one plain line at most every `LINE_EVERY_S` seconds (and at the end). `enabled="streams"`
(`worldmind run --progress streams`) adds a bar per stream on a terminal, or one line per finished
episode otherwise.

`quiet_model_loading()` silences the "Loading weights" tqdm bars of transformers / sentence-transformers
(set WORLDMIND_LOADING_BARS=1 to keep them): they are noise between the run's own lines.
"""

from __future__ import annotations

import os
import sys
import time
from typing import Any

__all__ = ["Progress", "quiet_model_loading"]

LINE_EVERY_S = 30.0


def quiet_model_loading() -> None:
    """No model-loading progress bars (transformers reads HF_HUB_DISABLE_PROGRESS_BARS at import; an
    already imported transformers is told directly)."""
    if os.environ.get("WORLDMIND_LOADING_BARS") == "1":
        return
    os.environ["HF_HUB_DISABLE_PROGRESS_BARS"] = "1"
    if "transformers" in sys.modules:
        try:
            from transformers.utils import logging as hf_logging

            hf_logging.disable_progress_bar()
        except Exception:  # an odd transformers build only keeps its bars
            pass
    if "huggingface_hub" in sys.modules:
        try:
            from huggingface_hub.utils import disable_progress_bars

            disable_progress_bars()
        except Exception:
            pass


class _Bar:
    """One stream's share of the run (and its own bar/lines when detail was asked for)."""

    def __init__(self, owner: Progress, name: str, total: int, position: int) -> None:
        self.owner = owner
        self.name = name
        self.total = total
        self.done = 0
        self.successes = 0
        self._tqdm = None
        if owner.tty and owner.detail:
            from tqdm import tqdm

            self._tqdm = tqdm(total=total, desc=name[-48:], position=position + 1, leave=True,
                              dynamic_ncols=True, unit="ep")

    def skip(self, n: int) -> None:
        """Episodes already on disk (resume): counted as done, not as throughput."""
        self.done += n
        self.owner._skipped(n, finished_stream=bool(n) and self.done >= self.total)
        if self._tqdm is not None and n:
            self._tqdm.update(n)

    def update(self, record: dict[str, Any]) -> None:
        self.done += 1
        self.successes += bool(record.get("success"))
        if self._tqdm is not None:
            self._tqdm.update(1)
            self._tqdm.set_postfix(sr=f"{self.successes}/{self.done}")
        elif self.owner.detail and self.owner.enabled is not False:
            print(f"[{self.name}] episode {record.get('index')} "
                  f"{'success' if record.get('success') else record.get('taxonomy', 'fail')} "
                  f"progress={float(record.get('progress') or 0):.2f} ({self.done}/{self.total})",
                  file=sys.stderr, flush=True)
        self.owner._episode(bool(record.get("success")), finished_stream=self.done == self.total)

    def close(self) -> None:
        if self._tqdm is not None:
            self._tqdm.close()


class Progress:
    """`enabled`: None = a bar on a terminal, lines otherwise; True = bar; False = lines; "streams" = as
    None plus per-stream detail."""

    def __init__(self, enabled: bool | str | None = None) -> None:
        self.detail = enabled == "streams"
        self.enabled = None if self.detail else enabled
        self.tty = self.enabled is True or (self.enabled is None and sys.stderr.isatty())
        self.bars: list[_Bar] = []
        self.total = 0
        self.done = 0
        self.resumed = 0
        self.successes = 0
        self.streams_finished = 0
        self._overall: Any = None
        self._t0 = time.monotonic()
        self._last_line = 0.0

    def add(self, name: str, total: int) -> _Bar:
        bar = _Bar(self, name, total, len(self.bars))
        self.bars.append(bar)
        self.total += total
        if self._overall is not None:
            self._overall.total = self.total
            self._overall.refresh()
        return bar

    # -- the overall bar / line -------------------------------------------------------------------

    def _bar(self) -> Any:
        if self._overall is None and self.tty:
            from tqdm import tqdm

            self._overall = tqdm(total=self.total, desc=f"{len(self.bars)} streams", position=0, leave=True,
                                 dynamic_ncols=True, unit="ep", smoothing=0.1)
        return self._overall

    def _skipped(self, n: int, *, finished_stream: bool) -> None:
        self.done += n
        self.resumed += n
        self.streams_finished += finished_stream
        bar = self._bar()
        if bar is not None:
            # resumed episodes count as done but not as throughput: move the bar without a rate sample
            bar.n += n
            bar.last_print_n += n
            bar.total = self.total
            bar.set_description(f"{len(self.bars)} streams", refresh=False)
            bar.refresh()

    def _episode(self, success: bool, *, finished_stream: bool) -> None:
        self.done += 1
        self.successes += success
        self.streams_finished += finished_stream
        bar = self._bar()
        if bar is not None:
            bar.update(1)
            bar.set_postfix(streams=f"{self.streams_finished}/{len(self.bars)}",
                            success=f"{self.successes}/{self.done - self.resumed}", refresh=False)
        else:
            now = time.monotonic()
            if now - self._last_line >= LINE_EVERY_S or self.done >= self.total:
                self._last_line = now
                print(self.line(now), file=sys.stderr, flush=True)

    def line(self, now: float | None = None) -> str:
        """The overall state as one plain line (done/total, throughput, ETA)."""
        elapsed = max(1e-9, (now or time.monotonic()) - self._t0)
        ran = self.done - self.resumed
        rate = ran / elapsed
        left = self.total - self.done
        eta = f"{left / rate:.0f}s" if rate > 0 else "?"
        return (f"progress: {self.done}/{self.total} episodes ({100 * self.done / max(1, self.total):.0f}%), "
                f"{rate * 60:.1f} ep/min, ETA {eta}, streams finished {self.streams_finished}/{len(self.bars)}, "
                f"successes {self.successes}/{ran}")

    def close(self) -> None:
        for bar in self.bars:
            bar.close()
        if self._overall is not None:
            self._overall.close()
