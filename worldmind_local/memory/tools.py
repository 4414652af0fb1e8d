"""`worldmind memory show|stats|filter|merge|diff`: look into repositories and derive new ones.

Every tool reads its inputs through `sources.open_source` (a run, a `memory/`, an export, parquet,
`hub:`), so bad or foreign input is the same one line naming the file and the field everywhere. Tools
that produce a repository (`filter`, `merge`) write a new export folder (`hub.write_export`) and never
touch their inputs; the output records what it was derived from (each input's content hash).

Merging World Knowledge Repositories replays every entry, in input order, through a fresh repository's
own admission rule (near-duplicates at cosine >= 0.95 of the same partition are dropped), so a merge is
what one stream would have kept had it seen the inputs in that order. Entry ids are content hashes, so
they are stable across merges and runs; a merge refuses inputs that would give two different entries
one id. Baselines' stores have no text embedding: their merge drops exact repeats (same id).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

from worldmind_local.memory.entries import MemoryDataError
from worldmind_local.memory.sources import EMBEDDINGS, MemorySource, Repository

__all__ = ["show_lines", "stats", "stats_lines", "filter_repository", "merge", "diff", "diff_lines",
           "parse_range"]

_PROVENANCE_KEYS = ("benchmark", "subset", "method", "planner", "judge", "run_id", "stream_id", "git_sha",
                    "suite", "data_sha256", "episodes")


def _short(text: Any, width: int) -> str:
    flat = " ".join(str(text or "").split())
    return flat if len(flat) <= width else flat[: width - 3] + "..."


def show_lines(source: MemorySource, repo: Repository, *, limit: int | None = None,
               partition: str | None = None) -> list[str]:
    """A header with the repository's provenance, then one line per entry with its own provenance."""
    prov = source.provenance
    planner = prov.get("planner")
    model = planner.get("model_id") if isinstance(planner, dict) else planner
    lines = [f"{source.value}  ({source.kind}, {source.location})",
             f"  sha256 {source.sha256}  entries {source.entries}  "
             + "  ".join(f"{k} {v}" for k, v in source.counts.items()),
             f"  from run {prov.get('run_id') or '?'} stream {prov.get('stream_id') or '?'}: method "
             f"{prov.get('method') or '?'}, planner {model or '?'}, on {'+'.join(prov.get('benchmarks') or [])}"]
    column = repo.partition_column
    shown = 0
    for row in repo.rows():
        if partition is not None and row[column] != partition:
            continue
        if limit is not None and shown >= limit:
            lines.append(f"  ... ({limit} shown; --limit to see more)")
            break
        lines.append(f"  {row['id']}  {row[column]:<8} {row['benchmark']}/{row['subset']} ep {row['episode']:<3} "
                     f"{row.get('planner_model') or '-'}  {_short(row['text'], 90)}")
        shown += 1
    return lines


def stats(repo: Repository) -> dict[str, Any]:
    """Counts per partition, per source task (benchmark/subset/task_id) and per model."""
    rows = repo.rows()
    column = repo.partition_column
    models: Counter[str] = Counter()
    for row in rows:
        for role in ("planner_model", "judge_model"):
            if row.get(role):
                models[f"{role.split('_')[0]}:{row[role]}"] += 1
    return {
        "entries": len(rows),
        "partition": dict(Counter(row[column] for row in rows)),
        "benchmark": dict(Counter(row["benchmark"] for row in rows)),
        "source_task": dict(Counter(f"{row['benchmark']}/{row['subset']}/{row['task_id']}" for row in rows)),
        "model": dict(models),
    }


def stats_lines(source: MemorySource, counts: dict[str, Any]) -> list[str]:
    lines = [f"{source.value}: {counts['entries']} entries, sha256 {source.sha256[:16]}"]
    for name in ("partition", "benchmark", "model", "source_task"):
        lines.append(f"  per {name.replace('_', ' ')}:")
        lines += [f"    {n:>5}  {key}" for key, n in sorted(counts[name].items(), key=lambda kv: (-kv[1], kv[0]))]
    return lines


def parse_range(text: str | None) -> tuple[int | None, int | None]:
    """`A:B` (A <= episode < B; either side may be empty) or a single episode `A`."""
    if not text:
        return None, None
    lo, sep, hi = text.partition(":")
    try:
        if not sep:
            return int(lo), int(lo) + 1
        return (int(lo) if lo.strip() else None), (int(hi) if hi.strip() else None)
    except ValueError:
        raise ValueError(f"--episodes expects A:B, A: , :B or A (integers), got {text!r}") from None


def _derived(source: MemorySource) -> dict[str, Any]:
    return {"value": source.value, "kind": source.kind, "sha256": source.sha256, "entries": source.entries,
            **{k: source.provenance.get(k) for k in ("run_id", "stream_id", "benchmark", "method")}}


def filter_repository(source: MemorySource, repo: Repository, *, partitions: list[str] | None = None,
                      benchmarks: list[str] | None = None, models: list[str] | None = None,
                      episodes: tuple[int | None, int | None] = (None, None)) -> Repository:
    """The entries matching every given condition, in their order, with the input's settings and
    provenance plus what it was filtered from and how."""
    import pyarrow as pa

    column = repo.partition_column
    lo, hi = episodes
    keep = []
    for row in repo.rows():
        row_models = {row.get("planner_model"), row.get("judge_model")}
        keep.append((partitions is None or row[column] in partitions)
                    and (benchmarks is None or row["benchmark"] in benchmarks)
                    and (models is None or bool(row_models & set(models)))
                    and (lo is None or row["episode"] >= lo) and (hi is None or row["episode"] < hi))
    table = repo.table.filter(pa.array(keep, type=pa.bool_()))
    rule = {k: v for k, v in (("partition", partitions), ("benchmark", benchmarks), ("model", models),
                              ("episodes", [lo, hi] if (lo, hi) != (None, None) else None)) if v is not None}
    provenance = {**repo.provenance, "derived_from": [_derived(source)], "filter": rule}
    return Repository(table, dict(repo.meta), provenance, repo.where)


# -- merge ------------------------------------------------------------------------------------------

@dataclass
class _FixedEmbedder:
    """Stands in for the embedder a merged repository was built with: entries arrive embedded, so it is
    only asked for its id and dimension."""

    model_id: str
    dim: int


def _common_settings(inputs: list[tuple[MemorySource, Repository]]) -> tuple[str, int, str]:
    first_source, first = inputs[0]
    embedder = first.meta.get("embedder_model_id")
    for source, repo in inputs[1:]:
        if repo.partition_column != first.partition_column:
            raise MemoryDataError(repo.where, first.partition_column,
                                  f"column missing: {source.value} is a {repo.memory_format} repository, "
                                  f"{first_source.value} a {first.memory_format} one; they cannot be merged")
        if repo.dim != first.dim:
            raise MemoryDataError(repo.where, "key_embedding", f"{repo.dim}-dim vectors, {first_source.value} "
                                                               f"has {first.dim}")
        other = repo.meta.get("embedder_model_id")
        if embedder and other and other != embedder:
            raise MemoryDataError(repo.where, "embedder_model_id", f"{other}, {first_source.value} used {embedder}")
    return embedder or "unknown", first.dim, first.partition_column


def _merge_wkr(inputs: list[tuple[MemorySource, Repository]], embedder: str, dim: int,
               dedup_threshold: float) -> tuple[Any, dict[str, Any], dict[str, int]]:
    from worldmind_local.memory.entries import ExperienceEntry
    from worldmind_local.memory.repository import WorldKnowledgeRepository

    merged = WorldKnowledgeRepository(_FixedEmbedder(embedder, dim), budget=None,  # type: ignore[arg-type]
                                      dedup_threshold=dedup_threshold)
    dropped = Counter[str]()
    for source, repo in inputs:
        for row_no, row in enumerate(repo.rows(with_embeddings=True)):
            if any(row.get(name) is None for name in EMBEDDINGS):
                raise MemoryDataError(f"{repo.files[row_no] if repo.files else repo.where} row {row_no}",
                                      "text_embedding", "missing; a merge needs both vectors of every entry")
            if not merged.add_embedded(ExperienceEntry(**{k: v for k, v in row.items() if k in
                                                          ExperienceEntry.model_fields})):
                dropped[source.value] += 1
    table = merged.to_dataset().with_format("arrow")[:]
    meta = {k: v for k, v in merged.metadata().items() if k != "commits"}
    meta["format"] = "worldmind_local.wkr/1"
    return table, meta, dict(dropped)


def _merge_store(inputs: list[tuple[MemorySource, Repository]]) -> tuple[Any, dict[str, Any], dict[str, int]]:
    import pyarrow as pa

    seen: set[str] = set()
    tables, dropped = [], Counter[str]()
    for source, repo in inputs:
        keep = []
        for entry_id in repo.table.column("id").to_pylist():
            keep.append(entry_id not in seen)
            dropped[source.value] += entry_id in seen
            seen.add(entry_id)
        tables.append(repo.table.replace_schema_metadata(None).filter(pa.array(keep, type=pa.bool_())))
    table = pa.concat_tables(tables, promote_options="permissive")
    meta = {k: v for k, v in inputs[0][1].meta.items() if k not in ("commits", "counts")}
    return table, {**meta, "format": "worldmind_local.store/1", "budget": None}, dict(dropped)


def merge(inputs: list[tuple[MemorySource, Repository]], *, dedup_threshold: float = 0.95) -> tuple[Repository, dict[str, int]]:
    """One repository from several, in input order, near-duplicates dropped. Returns it and how many
    entries each input lost to dedup."""
    if len(inputs) < 2:
        raise ValueError("merge needs at least two repositories")
    embedder, dim, column = _common_settings(inputs)
    if column == "partition":
        table, meta, dropped = _merge_wkr(inputs, embedder, dim, dedup_threshold)
    else:
        table, meta, dropped = _merge_store(inputs)
    provenance: dict[str, Any] = {"derived_from": [_derived(source) for source, _ in inputs]}
    for key in _PROVENANCE_KEYS:   # a fact all inputs share stays; one they disagree on does not
        values = [source.provenance.get(key) for source, _ in inputs]
        if all(v == values[0] for v in values):
            provenance[key] = values[0]
    return Repository(table, meta, provenance, "merge"), dropped


# -- diff -------------------------------------------------------------------------------------------

def diff(a: Repository, b: Repository) -> dict[str, Any]:
    """Entries only in a, only in b, and with the same id but different content; differing settings."""
    rows_a = {r["id"]: r for r in a.rows(with_embeddings=True)}
    rows_b = {r["id"]: r for r in b.rows(with_embeddings=True)}
    settings = {k: [a.meta.get(k), b.meta.get(k)] for k in ("embedder_model_id", "dim", "dedup_threshold",
                                                               "budget", "budget_unit", "dedup")
                if a.meta.get(k) != b.meta.get(k)}
    return {
        "only_a": [i for i in rows_a if i not in rows_b],
        "only_b": [i for i in rows_b if i not in rows_a],
        "changed": [i for i in rows_a if i in rows_b and rows_a[i] != rows_b[i]],
        "same": sum(1 for i in rows_a if i in rows_b and rows_a[i] == rows_b[i]),
        "settings": settings,
        "rows_a": rows_a, "rows_b": rows_b,
    }


def diff_lines(sa: MemorySource, sb: MemorySource, result: dict[str, Any], *, limit: int = 20) -> list[str]:
    lines = [f"a: {sa.value} ({sa.entries} entries, sha256 {sa.sha256[:16]})",
             f"b: {sb.value} ({sb.entries} entries, sha256 {sb.sha256[:16]})",
             f"same {result['same']}  only in a {len(result['only_a'])}  only in b {len(result['only_b'])}  "
             f"changed {len(result['changed'])}"]
    lines += [f"setting {k}: a {va!r}, b {vb!r}" for k, (va, vb) in result["settings"].items()]
    for mark, ids, rows in (("-", result["only_a"], result["rows_a"]), ("+", result["only_b"], result["rows_b"]),
                            ("~", result["changed"], result["rows_a"])):
        for entry_id in ids[:limit]:
            row = rows[entry_id]
            lines.append(f"{mark} {entry_id}  {row['benchmark']}/{row['subset']} ep {row['episode']}  "
                         f"{_short(row['text'], 80)}")
        if len(ids) > limit:
            lines.append(f"{mark} ... {len(ids) - limit} more")
    return lines
