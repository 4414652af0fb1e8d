"""`worldmind report`: the paper's tables, figures and an episode viewer from any set of run folders.

- `load`: run folders -> streams (spec, facts, episode records); `stats`: the statistics (scipy);
- `tables`, `tables_paired`: the paper's tables; `render`: Markdown, LaTeX, CSV, HTML;
- `figures`: matplotlib figures (PNG + SVG); `viewer`: the static HTML site; `build`: all of it.

Nothing here imports matplotlib or a model at import time.
"""

from __future__ import annotations

from worldmind_local.reporting.build import FORMATS, build_tables, write_report
from worldmind_local.reporting.load import Run, Stream, load_runs

__all__ = ["FORMATS", "build_tables", "write_report", "load_runs", "Run", "Stream"]
