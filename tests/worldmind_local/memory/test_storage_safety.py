"""The saved repository's file modes (issue 18, point 9) and damaged saved datasets (point 6)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import datasets
import pytest

from worldmind_local.memory import MemoryDataError, WorldKnowledgeRepository
from worldmind_local.memory.storage import _umask, atomic_save_dataset, load_saved_dataset


def _modes(folder: Path) -> set[tuple[str, int]]:
    return {("dir" if p.is_dir() else "file", stat.S_IMODE(p.stat().st_mode)) for p in [folder, *folder.rglob("*")]}


@pytest.mark.parametrize("mask", [0o022, 0o027])
def test_saved_memory_has_the_modes_of_a_plain_mkdir(embedder, tmp_path: Path, mask: int) -> None:
    old = os.umask(mask)
    try:
        assert _umask() == mask
        WorldKnowledgeRepository(embedder).save(tmp_path / "memory")
        WorldKnowledgeRepository(embedder).save(tmp_path / "memory")  # the atomic swap keeps them too
        plain = tmp_path / "plain"
        plain.mkdir()
        (plain / "f").write_text("x")
    finally:
        os.umask(old)
    assert _modes(tmp_path / "memory") == {("dir", stat.S_IMODE(plain.stat().st_mode)),
                                           ("file", stat.S_IMODE((plain / "f").stat().st_mode))}
    if mask == 0o022:
        assert _modes(tmp_path / "memory") == {("dir", 0o755), ("file", 0o644)}


def test_dataset_dict_subfolders_get_plain_modes_too(tmp_path: Path) -> None:
    dd = datasets.DatasetDict({"process": datasets.Dataset.from_dict({"text": ["a"]}),
                               "goal": datasets.Dataset.from_dict({"text": ["b"]})})
    old = os.umask(0o022)
    try:
        atomic_save_dataset(dd, tmp_path / "dd")
    finally:
        os.umask(old)
    assert _modes(tmp_path / "dd") == {("dir", 0o755), ("file", 0o644)}


def _corrupt(path: Path, how: str) -> None:
    data = bytearray(path.read_bytes())
    if how == "truncate":
        data = data[: len(data) // 2]
    elif how == "garbage":
        data[200:260] = b"\xff" * 60
    elif how == "empty":
        data = bytearray()
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("how", ["truncate", "garbage", "empty"])
def test_a_corrupt_arrow_file_names_the_file(tmp_path: Path, how: str) -> None:
    ds = datasets.Dataset.from_dict({"text": [f"row {i} " * 10 for i in range(500)]})
    atomic_save_dataset(ds, tmp_path / "memory")
    arrow = next((tmp_path / "memory").glob("*.arrow"))
    _corrupt(arrow, how)
    with pytest.raises(MemoryDataError) as err:
        load_saved_dataset(tmp_path / "memory")
    assert err.value.where == str(arrow) and "\n" not in str(err.value)


def test_a_broken_dataset_info_names_the_file(tmp_path: Path) -> None:
    atomic_save_dataset(datasets.Dataset.from_dict({"text": ["a"]}), tmp_path / "memory")
    (tmp_path / "memory" / "dataset_info.json").write_bytes(b"{\xff")
    with pytest.raises(MemoryDataError, match="dataset_info.json"):
        load_saved_dataset(tmp_path / "memory")
    with pytest.raises(FileNotFoundError):
        load_saved_dataset(tmp_path / "absent")


def test_an_intact_folder_loads(tmp_path: Path) -> None:
    atomic_save_dataset(datasets.Dataset.from_dict({"text": ["a", "b"]}), tmp_path / "memory")
    assert load_saved_dataset(tmp_path / "memory")["text"] == ["a", "b"]
