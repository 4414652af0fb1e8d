"""Shared fixtures. EmbodiedBench data is read from ../shared/embodiedbench; tests that need it skip
with a clear reason only where that folder is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("WORLDMIND_TEST_DATA", REPO.parent / "shared" / "embodiedbench"))

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("TRANSFORMERS_OFFLINE", "1")
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")
os.environ.setdefault("TOKENIZERS_PARALLELISM", "false")


@pytest.fixture(scope="session")
def eb_data_dir() -> Path:
    """The EmbodiedBench data pack (../shared/embodiedbench), or skip."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"EmbodiedBench data not found at {SHARED_DATA} (set WORLDMIND_TEST_DATA)")
    return SHARED_DATA
