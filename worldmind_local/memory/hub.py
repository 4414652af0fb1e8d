"""A memory as a Hugging Face Hub dataset repository: a card with provenance, parquet data, one-commit upload.

Layout of an export (what `worldmind memory export` writes and `push` uploads):

```
README.md                                   card: YAML metadata + prose generated from it
data/train-00000-of-00001.parquet           config `default`: every entry, in insertion order
data/<partition>/train-00000-of-00001.parquet   one config per partition (process, goal; or a store's kinds)
```

Nothing needs this package to read it: `datasets.load_dataset(DIR)` gives the default config with the
same rows and features as the run's `memory/` (the features are in the card and in each parquet file's
`huggingface` schema metadata); each partition is also loadable alone (`load_dataset(DIR, "process")`).
The per-partition configs repeat the default config's rows: a memory is small, and a reader of one
partition should not have to filter. The repository's settings (format, embedder, dimension, dedup
threshold, budget) and its provenance are in the card's `worldmind` YAML section and in each parquet
file's `worldmind_local` schema metadata, so a lone parquet file still says what it is.

An export is written to a temporary folder beside the target and renamed into place: the target is a
new folder, never a half-written one, and nothing is ever written into an existing folder.
"""

from __future__ import annotations

import copy
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from worldmind_local.memory.sources import CARD_KEY, PARQUET_META_KEY, Repository, open_source

__all__ = ["export", "write_export", "card_metadata", "card_text", "push", "PublishError", "new_folder",
           "size_category"]

DEFAULT_LICENSE = "cc-by-4.0"
_DESCRIPTIONS = {
    "process": "Process Experience: corrective rules the reflector wrote after a prediction error (the "
               "predicted state did not match the observed one)",
    "goal": "Goal Experience: workflows distilled from successful trajectories",
}


class PublishError(RuntimeError):
    """Publishing could not start or did not finish; nothing was committed."""


def size_category(n: int) -> str:
    """The Hub's size bucket for n rows."""
    bounds = [(1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"), (1_000_000, "100K<n<1M"),
              (10_000_000, "1M<n<10M")]
    return next((name for bound, name in bounds if n < bound), "10M<n<100M")


def new_folder(out: str | os.PathLike[str]) -> Path:
    """`out` as a folder that does not exist yet (or is empty): outputs never go into existing files."""
    path = Path(out).expanduser().resolve()
    if path.exists() and not (path.is_dir() and not any(path.iterdir())):
        raise FileExistsError(f"{path} exists; give a new folder (nothing is ever written in place)")
    return path


# -- the card ---------------------------------------------------------------------------------------

def _provenance(repo: Repository, sha256: str) -> dict[str, Any]:
    """Every provenance field, present even when unknown (null), in a stable order."""
    prov = repo.provenance
    column = repo.table.column
    counts = repo.counts()
    tasks = {(b, s, t) for b, s, t in zip(column("benchmark").to_pylist(), column("subset").to_pylist(),
                                          column("task_id").to_pylist(), strict=True)}
    entry_models = sorted({m for name in ("planner_model", "judge_model") if name in repo.table.column_names
                           for m in column(name).to_pylist() if m})
    keys = ("benchmark", "subset", "method", "planner", "judge", "run_id", "stream_id", "git_sha", "suite",
            "data_sha256", "episodes")
    out: dict[str, Any] = {k: prov.get(k) for k in keys}
    out.update({
        "embedder": {"model_id": repo.meta.get("embedder_model_id"), "dim": repo.dim},
        "memory_format": repo.memory_format,
        "partition_column": repo.partition_column,
        "sha256": sha256,
        "entries": repo.table.num_rows,
        "counts": counts,
        "source_tasks": len(tasks),
        "benchmarks": sorted({b for b, _, _ in tasks}),
        "subsets": sorted({s for _, s, _ in tasks}),
        "entry_models": entry_models,
    })
    for key in ("derived_from", "filter", "memory_from", "memory_sha256"):
        if prov.get(key) is not None:
            out[key] = prov[key]
    # the settings a loader needs; the source stream's own commit log is not part of a published repository
    settings = {k: v for k, v in repo.meta.items() if k != "commits"}
    out["repository"] = {**settings, "format": repo.meta.get("format") or repo.memory_format, "dim": repo.dim,
                         "counts": counts}
    return out


def _config_info(name: str, features: list[Any], table: Any) -> dict[str, Any]:
    """One config's `dataset_info` entry (its own copy of the features: no YAML anchors in the card)."""
    return {"config_name": name, "features": copy.deepcopy(features),
            "splits": [{"name": "train", "num_bytes": int(table.nbytes), "num_examples": table.num_rows}]}


def card_metadata(repo: Repository, *, license: str = DEFAULT_LICENSE) -> Any:
    """The card's YAML as `huggingface_hub.DatasetCardData`: configs, features, license, tags, size, provenance."""
    import pyarrow.compute as pc
    from datasets import Features
    from huggingface_hub import DatasetCardData

    table = repo.table.replace_schema_metadata(None)
    features = Features.from_arrow_schema(table.schema)._to_yaml_list()
    counts = repo.counts()
    provenance = _provenance(repo, repo.sha256)
    configs = [{"config_name": "default", "default": True,
                "data_files": [{"split": "train", "path": "data/train-*.parquet"}]}]
    infos = [_config_info("default", features, table)]
    column = table.column(repo.partition_column)
    for name in counts:
        configs.append({"config_name": name, "data_files": [{"split": "train", "path": f"data/{name}/train-*.parquet"}]})
        infos.append(_config_info(name, features, table.filter(pc.equal(column, name))))
    tags = ["worldmind", "embodied-agents", "embodiedbench", "agent-memory",
            "world-knowledge-repository" if repo.partition_column == "partition" else "experience-store",
            *provenance["benchmarks"]]
    name = provenance.get("method") or "WorldMind"
    where = "/".join(str(x) for x in (provenance.get("benchmark"), provenance.get("subset")) if x) or ", ".join(
        provenance["benchmarks"])
    return DatasetCardData(
        license=license, language=["en"], size_categories=[size_category(table.num_rows)], tags=tags,
        pretty_name=f"{name} memory ({where})", configs=configs, dataset_info=infos, **{CARD_KEY: provenance},
    )


def _model_line(role: str, model: Any) -> str:
    if not isinstance(model, dict) or not model.get("spec"):
        return f"- {role}: not recorded"
    weights = model.get("weights_sha256")
    fingerprint = f", weights sha256 {weights[:16]}..." if weights else f" ({model.get('note') or 'no weight files'})"
    return f"- {role}: `{model.get('model_id') or model['spec']}` (spec `{model['spec']}`){fingerprint}"


def card_text(repo: Repository, *, license: str = DEFAULT_LICENSE) -> str:
    """The whole README.md: YAML front matter, then prose generated from the same metadata."""
    data = card_metadata(repo, license=license)
    prov = data.to_dict()[CARD_KEY]
    settings = prov["repository"]
    kinds = "\n".join(f"- `{name}` ({n} entries): {_DESCRIPTIONS.get(name, f'entries of kind {name!r}')}"
                      for name, n in prov["counts"].items()) or "- (no entries)"
    made = (f"run `{prov['run_id']}`, stream `{prov['stream_id']}` (method `{prov['method']}` on "
            f"`{prov['benchmark']}`/`{prov['subset']}`, {prov['episodes']} episodes of suite {prov['suite']}, "
            f"tasks sha256 `{prov['data_sha256']}`, code at git `{prov['git_sha']}`)"
            if prov.get("run_id") else "an unrecorded run (this repository came without run provenance)")
    derived = ""
    if prov.get("derived_from"):
        derived = "\n\nIt was derived from: " + "; ".join(
            f"`{d.get('sha256', '?')[:16]}` ({d.get('value', '?')})" for d in prov["derived_from"])
        if prov.get("filter"):
            derived += f", keeping the entries that match `{json.dumps(prov['filter'], sort_keys=True)}`"
        derived += "."
    budget = settings.get("budget")
    return f"""---
{data.to_yaml()}
---

# {data.pretty_name}

This dataset is the {'World Knowledge Repository' if prov['partition_column'] == 'partition' else 'experience store'}
that an embodied agent built while it worked through EmbodiedBench tasks in order (the WorldMind paper's
sequential online protocol): {prov['entries']} entries from {prov['source_tasks']} source tasks on
{', '.join(f'`{b}`' for b in prov['benchmarks']) or 'no benchmark'}.

{kinds}

## How the entries were made

They come from {made}.

{_model_line('planner', prov.get('planner'))}
{_model_line('judge', prov.get('judge'))}
- models named in the entries: {', '.join(f'`{m}`' for m in prov['entry_models']) or 'none'}

Each entry's `instruction` is its source task's instruction and the retrieval key: `key_embedding` is its
`{prov['embedder']['model_id']}` embedding ({prov['embedder']['dim']} dims, L2-normalised float32), and
`text_embedding` embeds `text` for the near-duplicate check (a new entry with cosine >=
{settings.get('dedup_threshold', 'n/a')} to one of its partition was discarded). Budget: {'none' if budget is None
else f"{budget} {settings.get('budget_unit')}"}. Every row carries its provenance (`benchmark`, `subset`,
`episode`, `task_id`, `planner_model`, `judge_model`, `run_id`); `id` is a hash of the entry's content and
provenance, so the same experience has the same id everywhere.{derived}

Content hash (rows and vectors): `{prov['sha256']}`.

## Use

```python
from datasets import load_dataset
rows = load_dataset("path/or/owner/name")["train"]            # every entry, in insertion order
process = load_dataset("path/or/owner/name", "{next(iter(prov['counts']), 'process')}")["train"]   # one partition
```

With WorldMind-Local: `worldmind run ... --memory-from hub:OWNER/NAME` (from the local Hub cache) or
`--memory-from DIR`.
"""


# -- writing ----------------------------------------------------------------------------------------

def _write_parquet(table: Any, path: Path, provenance: dict[str, Any]) -> None:
    import pyarrow.parquet as pq
    from datasets import Features

    plain = table.replace_schema_metadata(None)
    features = Features.from_arrow_schema(plain.schema)
    meta = {b"huggingface": json.dumps({"info": {"features": features.to_dict()}}).encode(),
            PARQUET_META_KEY: json.dumps({"repository": provenance["repository"],
                                          "provenance": {k: v for k, v in provenance.items() if k != "repository"}},
                                         sort_keys=True, default=str).encode()}
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(plain.replace_schema_metadata(meta), path)


def _group_readable(folder: Path) -> None:
    """0755 folders, 0644 files, whatever the umask and mkdtemp's 0700 (a published repository is shared)."""
    for root, dirs, files in os.walk(folder):
        os.chmod(root, 0o755)
        for name in dirs:
            os.chmod(os.path.join(root, name), 0o755)
        for name in files:
            os.chmod(os.path.join(root, name), 0o644)


def write_export(repo: Repository, out: str | os.PathLike[str], *, license: str = DEFAULT_LICENSE) -> Path:
    """Write `repo` as a Hub dataset repository folder at `out` (new), all at once. Returns the folder."""
    import pyarrow.compute as pc

    target = new_folder(out)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=target.parent))
    try:
        text = card_text(repo, license=license)
        provenance = _provenance(repo, repo.sha256)
        table = repo.table.replace_schema_metadata(None)
        _write_parquet(table, tmp / "data" / "train-00000-of-00001.parquet", provenance)
        column = table.column(repo.partition_column)
        for name in repo.counts():
            part = table.filter(pc.equal(column, name))
            _write_parquet(part, tmp / "data" / name / "train-00000-of-00001.parquet", provenance)
        (tmp / "README.md").write_text(text, encoding="utf-8")
        _group_readable(tmp)
        if target.exists():
            target.rmdir()   # an empty folder the user made for it
        os.rename(tmp, target)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return target


def export(value: str, out: str | os.PathLike[str], *, license: str = DEFAULT_LICENSE) -> tuple[Path, Any]:
    """`worldmind memory export`: read any source (run, memory/, export, parquet, hub:) and write it out."""
    new_folder(out)   # refuse before reading anything
    source, repo = open_source(value)
    return write_export(repo, out, license=license), source


# -- publishing -------------------------------------------------------------------------------------

def _offline() -> bool:
    return os.environ.get("HF_HUB_OFFLINE", "").strip().lower() in ("1", "true", "yes", "on")


def push(value: str, repo_id: str, *, private: bool = False, revision: str | None = None,
         token: str | None = None, endpoint: str | None = None, license: str = DEFAULT_LICENSE) -> Any:
    """Publish an export (or any source, exported first) to the Hub as ONE commit; returns its CommitInfo.

    Everything that can be checked locally (offline mode, a token, a readable repository, the card) is
    checked before the first request; the data then goes up in a single `create_commit`, so a failure
    leaves the Hub repository as it was (at most created empty)."""
    from huggingface_hub import CommitOperationAdd, HfApi, get_token

    if _offline():
        raise PublishError("HF_HUB_OFFLINE is set: cannot publish while offline; nothing was published")
    token = token or get_token()
    if not token:
        raise PublishError("not logged in to the Hugging Face Hub: set HF_TOKEN or run `hf auth login`; "
                           "nothing was published")
    scratch: Path | None = None
    try:
        folder = Path(value).expanduser() if not value.startswith("hub:") else None
        if folder is None or not (folder / "README.md").is_file() or not (folder / "data").is_dir():
            scratch = Path(tempfile.mkdtemp(prefix="worldmind-push-"))
            folder, _ = export(value, scratch / "export", license=license)
        else:
            open_source(str(folder))   # the export must read back before anything is sent
        files = sorted(p for p in folder.rglob("*") if p.is_file())
        api = HfApi(endpoint=endpoint or os.environ.get("HF_ENDPOINT") or None, token=token)
        operations = [CommitOperationAdd(path_in_repo=p.relative_to(folder).as_posix(), path_or_fileobj=str(p))
                      for p in files]
        return _send(api, repo_id, operations, private=private, revision=revision)
    finally:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)


def _send(api: Any, repo_id: str, operations: list[Any], *, private: bool, revision: str | None) -> Any:
    import httpx2
    from huggingface_hub.errors import HfHubHTTPError, OfflineModeIsEnabled

    try:
        api.create_repo(repo_id, repo_type="dataset", private=private, exist_ok=True)
        if revision:
            api.create_branch(repo_id, repo_type="dataset", branch=revision, exist_ok=True)
        return api.create_commit(repo_id, operations, repo_type="dataset", revision=revision,
                                 commit_message=f"Add WorldMind memory ({len(operations)} files)")
    except OfflineModeIsEnabled:
        raise PublishError("huggingface_hub is in offline mode: nothing was published") from None
    except HfHubHTTPError as exc:
        status = exc.response.status_code if exc.response is not None else "?"
        hint = " (is the token valid, with write access?)" if status in (401, 403) else ""
        raise PublishError(f"the Hub at {api.endpoint} refused ({status}{hint}): "
                           f"{' '.join(str(exc).split())[:200]}; nothing was published") from None
    except (httpx2.HTTPError, OSError) as exc:
        raise PublishError(f"cannot reach the Hub at {api.endpoint} ({type(exc).__name__}); "
                           "nothing was published") from None

