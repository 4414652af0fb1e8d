"""The memory package is cheap to import: no torch, datasets or sentence-transformers until used."""

from __future__ import annotations

import subprocess
import sys


def test_import_pulls_in_no_heavy_library() -> None:
    code = ("import sys, worldmind_local.memory as m; assert m.__all__; "
            "print(','.join(k for k in ('torch', 'datasets', 'sentence_transformers', 'pyarrow') if k in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
