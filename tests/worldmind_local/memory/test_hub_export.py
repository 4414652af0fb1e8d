"""A run's memory as a Hub dataset repository, and every form `--memory-from` reads, on a real (small) run:

- export writes a card + parquet that `datasets.load_dataset(DIR)` reads with the memory's rows and
  features, without this package; the card's YAML parses with huggingface_hub and carries provenance;
- run, memory/, export, parquet file and parquet folder all give the same content hash and the same
  retrieval results when loaded by the method;
- fuzzed repositories fail in one line naming the file and the field, and no file is touched;
- show / stats / filter / merge / diff.
"""

from __future__ import annotations

import shutil
import stat
from pathlib import Path

import numpy as np
import pytest

from worldmind_local.cli import main
from worldmind_local.memory.entries import MemoryDataError
from worldmind_local.memory.sources import load_for_method, open_source

STREAM = "eb_alfred.base.worldmind.seeded-random.s0"
PROVENANCE = ("benchmark", "subset", "method", "planner", "judge", "embedder", "run_id", "git_sha", "suite",
              "data_sha256", "entries", "counts", "sha256")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A WorldMind run with the model-free planner whose repository holds a few Process Experience entries."""
    out = tmp_path_factory.mktemp("src") / "run"
    assert main(["run", "--benchmark", "eb_alfred", "--subsets", "base", "--suite", "generated", "--suite-size",
                 "8", "--planner", "random:seeded-random", "--progress", "lines", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def export_dir(run, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("exp") / "repo"
    assert main(["memory", "export", str(run), str(out)]) == 0
    return out


def _snapshot(folder: Path) -> dict[str, tuple[bytes, int]]:
    return {str(p): (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(folder.rglob("*")) if p.is_file()}


def test_load_dataset_reads_the_export_with_the_same_rows_and_features(run, export_dir):
    import datasets

    memory = datasets.load_from_disk(str(run / "streams" / STREAM / "memory"))
    assert len(memory) > 0
    loaded = datasets.load_dataset(str(export_dir))
    assert list(loaded) == ["train"]
    assert loaded["train"].features == memory.features
    assert loaded["train"].to_list() == memory.to_list()
    part = datasets.load_dataset(str(export_dir), "process")["train"]
    assert part.to_list() == [r for r in memory.to_list() if r["partition"] == "process"]


def test_card_yaml_parses_and_carries_every_provenance_field(run, export_dir):
    from huggingface_hub import DatasetCard

    card = DatasetCard.load(export_dir / "README.md")
    data = card.data.to_dict()
    assert data["license"] == "cc-by-4.0" and "worldmind" in data["tags"] and data["size_categories"] == ["n<1K"]
    assert {c["config_name"] for c in data["configs"]} >= {"default", "process"}
    prov = data["worldmind"]
    assert set(PROVENANCE) <= set(prov)
    assert prov["benchmark"] == "eb_alfred" and prov["subset"] == "base" and prov["method"] == "worldmind"
    assert prov["planner"]["spec"] == "random:seeded-random" and prov["planner"]["model_id"] == "seeded-random"
    assert "weights_sha256" in prov["planner"] and "weights_sha256" in prov["judge"]
    assert prov["embedder"] == {"model_id": "sentence-transformers/all-MiniLM-L6-v2", "dim": 384}
    assert prov["run_id"] == "run" and prov["stream_id"] == STREAM
    assert prov["data_sha256"] and prov["suite"].startswith("eb_alfred generated")
    assert prov["entries"] == sum(prov["counts"].values()) > 0
    # the prose is generated from the same metadata
    assert prov["sha256"] in card.text and "Process Experience" in card.text and STREAM in card.text


def test_export_is_group_readable(export_dir):
    for path in [export_dir, *export_dir.rglob("*")]:
        mode = stat.S_IMODE(path.stat().st_mode)
        assert mode == (0o755 if path.is_dir() else 0o644), (path, oct(mode))


def test_every_form_has_the_same_hash_and_retrieves_the_same(run, export_dir, tmp_path):
    from worldmind_local.memory import Embedder
    from worldmind_local.methods.worldmind import WorldMind

    folder = tmp_path / "parquet"
    folder.mkdir()
    shutil.copy(export_dir / "data" / "train-00000-of-00001.parquet", folder / "part.parquet")
    forms = [str(run), str(run / "streams" / STREAM / "memory"), str(export_dir),
             str(export_dir / "data" / "train-00000-of-00001.parquet"), str(folder)]
    embedder = Embedder()
    query = embedder.encode(["Put a chilled apple on the counter."])[0]
    results = []
    for form in forms:
        memory, source = load_for_method(form, WorldMind(), embedder, None)
        results.append((source.sha256, [e.id for e in memory.retrieve(query, "process", 3)],
                        [e.model_dump() for e in memory.entries(with_embeddings=True)]))
    assert all(r == results[0] for r in results)
    assert len(results[0][1]) > 0
    kinds = [open_source(f)[0].kind for f in forms]
    assert kinds == ["run", "memory", "export", "parquet", "parquet"]


def test_a_relative_path_from_another_folder_is_the_same_stream(run, export_dir, monkeypatch):
    from worldmind_local.runner.config import RunConfig, StreamSpec

    def spec(value: str) -> StreamSpec:
        return StreamSpec(benchmark="eb_alfred", subset="base", planner="random:seeded-random", memory_from=value)

    absolute = spec(str(export_dir))
    monkeypatch.chdir(export_dir.parent)
    relative = spec("repo")
    parquet = spec("repo/data/train-00000-of-00001.parquet")
    assert absolute.stream_id == relative.stream_id == parquet.stream_id
    assert RunConfig(streams=[absolute]).identity() == RunConfig(streams=[relative]).identity()
    assert absolute.memory_sha256 == open_source(str(run))[0].sha256


def _fuzzed(export_dir: Path, tmp_path: Path, name: str):
    import pyarrow as pa
    import pyarrow.parquet as pq

    target = tmp_path / name
    shutil.copytree(export_dir, target)
    data = target / "data" / "train-00000-of-00001.parquet"
    table = pq.read_table(data)
    if name == "truncated":
        data.write_bytes(data.read_bytes()[: data.stat().st_size // 2])
    elif name == "wrong_dim":
        short = pa.array([v[:100] for v in table.column("key_embedding").to_pylist()], pa.list_(pa.float32()))
        pq.write_table(table.set_column(table.column_names.index("key_embedding"), "key_embedding", short), data)
    elif name == "missing_column":
        pq.write_table(table.drop_columns(["instruction"]), data)
    elif name == "duplicate_ids":
        pq.write_table(pa.concat_tables([table, table.slice(0, 1)]), data)
    elif name == "foreign":
        pq.write_table(pa.table({"question": ["q"], "answer": ["a"]}), data)
    return target, data


@pytest.mark.parametrize("name, field", [
    ("truncated", "'<file>'"), ("wrong_dim", "'key_embedding'"), ("missing_column", "'instruction'"),
    ("duplicate_ids", "'id'"), ("foreign", "'partition'"),
])
def test_fuzzed_repositories_fail_in_one_line_and_touch_nothing(export_dir, tmp_path, capsys, name, field):
    target, data = _fuzzed(export_dir, tmp_path, name)
    before = _snapshot(tmp_path)
    with pytest.raises(MemoryDataError) as info:
        open_source(str(target))
    message = str(info.value)
    assert "\n" not in message and str(data) in message and field in message
    for argv in (["memory", "stats", str(target)], ["memory", "export", str(target), str(tmp_path / "out")],
                 ["memory", "merge", str(target), str(export_dir), "--out", str(tmp_path / "merged")],
                 ["run", "--benchmark", "eb_alfred", "--subsets", "base", "--suite", "generated", "--limit", "1",
                  "--planner", "random:seeded-random", "--progress", "lines", "--out", str(tmp_path / "r"),
                  "--memory-from", str(target)]):
        capsys.readouterr()
        rc = main(argv)
        err = capsys.readouterr().err
        if argv[0] == "memory":
            assert rc == 2 and str(data) in err and field in err and "Traceback" not in err
            assert len(err.strip().splitlines()) == 1
        else:   # the run goes on; the stream that cannot load its seed fails alone, naming the file
            assert rc == 1 and str(data) in (tmp_path / "r" / "results.json").read_text()
            shutil.rmtree(tmp_path / "r")
    assert _snapshot(tmp_path) == before
    assert not (tmp_path / "out").exists() and not (tmp_path / "merged").exists()


def test_outputs_never_go_into_an_existing_folder(run, export_dir, tmp_path, capsys):
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "keep.txt").write_text("mine")
    for argv in (["memory", "export", str(run), str(tmp_path / "busy")],
                 ["memory", "filter", str(run), str(tmp_path / "busy"), "--partition", "process"],
                 ["memory", "merge", str(run), str(export_dir), "--out", str(tmp_path / "busy")]):
        assert main(argv) == 2
        assert "exists; give a new folder" in capsys.readouterr().err
    assert [p.name for p in (tmp_path / "busy").iterdir()] == ["keep.txt"]


def test_tools_show_stats_filter_merge_diff(run, export_dir, tmp_path, capsys):
    source, repo = open_source(str(run))
    n = source.entries
    assert main(["memory", "show", str(run), "--limit", "2"]) == 0
    out = capsys.readouterr().out
    assert source.sha256 in out and "seeded-random" in out and "2 shown" in out
    assert main(["memory", "stats", str(export_dir), "--json"]) == 0
    import json

    stats = json.loads(capsys.readouterr().out)
    assert stats["entries"] == n and stats["partition"] == source.counts
    assert sum(stats["source_task"].values()) == n and stats["model"] == {"planner:seeded-random": n,
                                                                          "judge:seeded-random": n}
    episodes = sorted({r["episode"] for r in repo.rows()})
    assert main(["memory", "filter", str(run), str(tmp_path / "early"), "--episodes", f":{episodes[-1]}"]) == 0
    early, _ = open_source(str(tmp_path / "early"))
    assert 0 < early.entries < n and early.provenance["derived_from"][0]["sha256"] == source.sha256
    assert main(["memory", "filter", str(run), str(tmp_path / "none"), "--model", "nobody"]) == 0
    assert open_source(str(tmp_path / "none"))[0].entries == 0
    # merging a repository with itself and its export keeps each entry once, ids unchanged
    capsys.readouterr()
    assert main(["memory", "merge", str(run), str(export_dir), str(tmp_path / "early"),
                 "--out", str(tmp_path / "merged")]) == 0
    merged, merged_repo = open_source(str(tmp_path / "merged"))
    assert merged.entries == n and merged.sha256 == source.sha256
    assert [r["id"] for r in merged_repo.rows()] == [r["id"] for r in repo.rows()]
    assert f"{n + early.entries} near-duplicates dropped" in capsys.readouterr().out
    assert main(["memory", "diff", str(run), str(export_dir)]) == 0
    assert main(["memory", "diff", str(run), str(tmp_path / "early")]) == 1
    out = capsys.readouterr().out
    assert f"only in a {n - early.entries}" in out


def test_merge_drops_near_duplicates_across_sources(export_dir, tmp_path):
    """An entry whose text vector is within cosine 0.95 of a kept one is dropped even from another run."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from worldmind_local.memory.tools import merge

    other = tmp_path / "other"
    shutil.copytree(export_dir, other)
    data = other / "data" / "train-00000-of-00001.parquet"
    table = pq.read_table(data).slice(0, 1)
    vec = np.asarray(table.column("text_embedding").to_pylist()[0], dtype=np.float32)
    noise = np.random.default_rng(0).standard_normal(vec.size).astype(np.float32)
    near = vec + 0.05 * noise / np.linalg.norm(noise)
    near /= np.linalg.norm(near)
    assert 0.95 < float(near @ vec) < 0.9999
    table = table.set_column(table.column_names.index("text_embedding"), "text_embedding",
                             pa.array([near.tolist()], pa.list_(pa.float32(), vec.size)))
    table = table.set_column(table.column_names.index("id"), "id", pa.array(["other-0"]))
    table = table.set_column(table.column_names.index("run_id"), "run_id", pa.array(["other-run"]))
    pq.write_table(table, data)
    merged, dropped = merge([open_source(str(export_dir)), open_source(str(other))])
    assert dropped == {str(other): 1}
    assert "other-0" not in merged.table.column("id").to_pylist()


def test_memory_from_errors_are_one_line(run, tmp_path, monkeypatch):
    from worldmind_local.memory.sources import locate

    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hub"))
    with pytest.raises(FileNotFoundError, match="no such folder or file"):
        locate(str(tmp_path / "absent"))
    with pytest.raises(FileNotFoundError, match="not in the local Hub cache"):
        locate("hub:nobody/nothing@v1")
    two = tmp_path / "two"
    for sid in ("a", "b"):
        shutil.copytree(run / "streams" / STREAM, two / "streams" / sid)
    shutil.copy(run / "manifest.json", two / "manifest.json")
    with pytest.raises(ValueError, match="run folder with 2 streams; pick one.*a, b"):
        locate(str(two))
