"""`worldmind show RUN`: read back any model call of a run: its prompt (messages, sampling, schema) and
its answer, from the run's cache. Every episode record lists its calls with their request keys."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any


def register(sub: Any) -> None:
    p = sub.add_parser("show", help="print a stored model call (prompt and answer) of a run",
                       description="Without --call: list the episode's calls. With --call J: print call J's "
                                   "messages, sampling, schema and answer as stored in RUN/cache.sqlite.")
    p.add_argument("run", help="run folder")
    p.add_argument("--stream", default=None, help="stream id (default: the run's only stream)")
    p.add_argument("--episode", type=int, default=0, metavar="I", help="episode position in the stream (0-based)")
    p.add_argument("--call", default=None, metavar="J",
                   help="call number (0-based, as listed) or call key such as planner:0")
    p.add_argument("--json", action="store_true", help="print the call as one JSON object")
    p.set_defaults(func=main)


def _stream_dir(run: Path, stream: str | None) -> Path:
    streams = sorted(p for p in (run / "streams").glob("*") if p.is_dir()) if (run / "streams").is_dir() else []
    if not streams:
        raise FileNotFoundError(f"{run}: no streams/ folder (is this a run folder?)")
    if stream is None:
        if len(streams) > 1:
            raise ValueError(f"{run} holds {len(streams)} streams; pick one with --stream: "
                             + ", ".join(p.name for p in streams))
        return streams[0]
    folder = run / "streams" / stream
    if not folder.is_dir():
        raise ValueError(f"{run}: no stream {stream!r}; streams: {', '.join(p.name for p in streams)}")
    return folder


def _episode(folder: Path, index: int) -> dict[str, Any]:
    from worldmind_local.runner.artifacts import StreamDir

    records = StreamDir(folder).read_episodes()
    if not 0 <= index < len(records):
        raise ValueError(f"{folder}/episodes.jsonl: episode {index} not found ({len(records)} recorded)")
    return records[index]


def _pick(calls: list[dict[str, Any]], which: str) -> dict[str, Any]:
    for call in calls:
        if call.get("key") == which:
            return call
    try:
        return calls[int(which)]
    except (ValueError, IndexError):
        raise ValueError(f"--call {which}: no such call (use a number 0-{len(calls) - 1} or a key)") from None


def main(args: argparse.Namespace) -> int:
    from models.cache import ResponseCache

    run = Path(args.run)
    record = _episode(_stream_dir(run, args.stream), args.episode)
    calls = record.get("calls") or []
    if args.call is None:
        print(f"episode {record.get('index')} ({record.get('task_id')}): {record.get('instruction')}")
        for i, c in enumerate(calls):
            print(f"  {i:3d}  {c['key']:<16} {c['role']:<11} {c['prompt_tokens']:>6}+{c['completion_tokens']:<5} "
                  f"{c['request'][:12]}")
        return 0
    call = _pick(calls, args.call)
    cache_path = run / "cache.sqlite"
    if not cache_path.exists():
        raise FileNotFoundError(f"{cache_path}: no cache (was the run made with --no-cache?)")
    cache = ResponseCache(cache_path, create=False)
    try:
        request = cache.get_request(call["request"]) if hasattr(cache, "get_request") else None
        answer = cache.get(call["request"])
    finally:
        cache.close()
    if request is None:
        raise ValueError(f"{cache_path}: no stored request for call {call['key']} (key {call['request'][:12]})")
    out = {"call": call, "request": request, "answer": answer.texts if answer is not None else None}
    if args.json:
        json.dump(out, sys.stdout, ensure_ascii=False, indent=2)
        print()
        return 0
    print(f"# {call['key']} ({call['role']}, {call['model']}) request {call['request']}")
    print(f"sampling: {json.dumps(request.get('sampling'))}")
    for m in request.get("messages", []):
        content = m.get("content")
        if not isinstance(content, str):
            content = "\n".join(p.get("text", f"[{p.get('type')} {p.get('sha256', '')[:12]}]") for p in content)
        print(f"\n--- {m.get('role')} ---\n{content}")
    print("\n--- answer ---")
    print("\n".join(out["answer"] or ["(no answer stored)"]))
    return 0
