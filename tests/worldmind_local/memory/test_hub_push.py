"""Publishing with huggingface_hub against a local endpoint that records what the client sends, and
reading the result back from a Hub cache built the way huggingface_hub lays it out:

- `push` sends ONE commit holding the card and every parquet file (create repo, validate card,
  preupload, commit: no hand-written HTTP); `--private` and `--revision` reach the endpoint;
- offline, unauthenticated, unreachable or refused: one line, nothing committed;
- `hf_hub_download` from the endpoint into a temporary HF_HUB_CACHE, then `--memory-from hub:OWNER/NAME`
  read offline gives the same content hash and the same run as `--memory-from RUN`.

The endpoint (`RecordingHub`) is an http.server on 127.0.0.1 with a free port, answering just enough of
the Hub's API; it stops itself after `lifetime_s` (bounded) and at the end of each test.
"""

from __future__ import annotations

import base64
import hashlib
import json
import socket
import threading
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlparse

import pytest

from worldmind_local.cli import main
from worldmind_local.memory.hub import PublishError, push
from worldmind_local.memory.sources import open_source

STREAM = "eb_alfred.base.worldmind.seeded-random.s0"
BASE = ["run", "--benchmark", "eb_alfred", "--subsets", "base", "--suite", "generated", "--suite-size", "8",
        "--planner", "random:seeded-random", "--progress", "lines"]


@dataclass
class Recorded:
    method: str
    path: str
    headers: dict[str, str]
    body: bytes


@dataclass
class HubState:
    requests: list[Recorded] = field(default_factory=list)
    repos: dict[str, dict[str, Any]] = field(default_factory=dict)      # repo id -> {"private", "refs"}
    commits: dict[str, dict[str, bytes]] = field(default_factory=dict)  # commit sha -> files
    fail_commit: bool = False


class RecordingHub:
    def __init__(self, lifetime_s: float = 120.0) -> None:
        self.state = HubState()
        handler = _handler(self.state)
        self.server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}"
        self.thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self.timer = threading.Timer(lifetime_s, self.close)
        self.timer.daemon = True

    def __enter__(self) -> RecordingHub:
        self.thread.start()
        self.timer.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        self.timer.cancel()
        if self.thread.is_alive():
            self.server.shutdown()
        self.server.server_close()

    def paths(self, method: str | None = None) -> list[str]:
        return [r.path for r in self.state.requests if method is None or r.method == method]


def _handler(state: HubState) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args: Any) -> None:  # quiet
            return None

        def _record(self) -> bytes:
            length = int(self.headers.get("Content-Length") or 0)
            body = self.rfile.read(length) if length else b""
            state.requests.append(Recorded(self.command, self.path, dict(self.headers), body))
            return body

        def _base(self) -> str:
            return f"http://{self.headers.get('Host')}"

        def _json(self, status: int, payload: Any) -> None:
            data = json.dumps(payload).encode()
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        def do_POST(self) -> None:  # noqa: N802 - http.server's naming
            body = self._record()
            path = urlparse(self.path).path
            if path == "/api/repos/create":
                req = json.loads(body)
                repo_id = f"{req.get('organization') or 'user'}/{req['name']}" if "/" not in req["name"] else req["name"]
                state.repos.setdefault(repo_id, {"visibility": req.get("visibility"), "refs": {}})
                return self._json(200, {"url": f"{self._base()}/datasets/{repo_id}", "name": repo_id})
            if path == "/api/validate-yaml":
                return self._json(200, {})
            parts = path.split("/")   # /api/datasets/OWNER/NAME/<op>/<rev>
            if len(parts) >= 7 and parts[1:3] == ["api", "datasets"]:
                repo_id, op, rev = f"{parts[3]}/{parts[4]}", parts[5], unquote("/".join(parts[6:]))
                if op == "preupload":
                    files = json.loads(body)["files"]
                    return self._json(200, {"files": [{"path": f["path"], "uploadMode": "regular",
                                                       "shouldIgnore": False} for f in files]})
                if op == "branch":
                    state.repos[repo_id]["refs"].setdefault(rev, None)
                    return self._json(200, {})
                if op == "commit":
                    if state.fail_commit:
                        return self._json(500, {"error": "injected failure"})
                    files = {}
                    for line in body.splitlines():
                        item = json.loads(line)
                        if item["key"] == "file":
                            files[item["value"]["path"]] = base64.b64decode(item["value"]["content"])
                    sha = hashlib.sha1(body).hexdigest()
                    state.commits[sha] = files
                    state.repos[repo_id]["refs"][rev] = sha
                    return self._json(200, {"commitUrl": f"{self._base()}/datasets/{repo_id}/commit/{sha}",
                                            "commitOid": sha})
            return self._json(404, {"error": f"not here: {path}"})

        def _resolve(self, send_body: bool) -> None:
            self._record()
            parts = urlparse(self.path).path.split("/")   # /datasets/OWNER/NAME/resolve/REV/PATH...
            if len(parts) < 7 or parts[1] != "datasets" or parts[4] != "resolve":
                return self._json(404, {"error": "not here"})
            repo_id, rev, name = f"{parts[2]}/{parts[3]}", unquote(parts[5]), unquote("/".join(parts[6:]))
            sha = state.repos.get(repo_id, {}).get("refs", {}).get(rev, rev)
            data = state.commits.get(sha, {}).get(name)
            if data is None:
                self.send_response(404)
                self.send_header("X-Error-Code", "EntryNotFound")
                self.send_header("Content-Length", "0")
                self.end_headers()
                return
            self.send_response(200)
            self.send_header("X-Repo-Commit", sha)
            self.send_header("ETag", f'"{hashlib.sha256(data).hexdigest()}"')
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            if send_body:
                self.wfile.write(data)

        def do_HEAD(self) -> None:  # noqa: N802
            self._resolve(send_body=False)

        def do_GET(self) -> None:  # noqa: N802
            self._resolve(send_body=True)

    return Handler


# -- fixtures ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("src") / "run"
    assert main([*BASE, "--out", str(out)]) == 0
    return out


@pytest.fixture
def hub(monkeypatch):
    import huggingface_hub.constants as hf_constants

    # tests/conftest.py sets HF_HUB_OFFLINE=1 before huggingface_hub is imported; the endpoint is loopback
    monkeypatch.setattr(hf_constants, "HF_HUB_OFFLINE", False)
    with RecordingHub(lifetime_s=120) as server:
        monkeypatch.setenv("HF_ENDPOINT", server.url)
        monkeypatch.setenv("HF_TOKEN", "hf_local_test_token")
        monkeypatch.delenv("HF_HUB_OFFLINE", raising=False)
        yield server


def _commits(server: RecordingHub) -> list[Recorded]:
    return [r for r in server.state.requests if "/commit/" in r.path]


# -- tests ------------------------------------------------------------------------------------------

def test_push_is_one_commit_with_the_card_and_every_data_file(run, hub, tmp_path, capsys):
    export = tmp_path / "export"
    assert main(["memory", "export", str(run), str(export)]) == 0
    assert main(["memory", "push", str(export), "someone/wkr", "--private", "--revision", "v1"]) == 0
    assert "in one commit" in capsys.readouterr().out
    posts = hub.paths("POST")
    assert posts[0] == "/api/repos/create"
    assert json.loads(hub.state.requests[0].body)["visibility"] == "private"
    assert "/api/datasets/someone/wkr/branch/v1" in posts
    assert any(p.startswith("/api/datasets/someone/wkr/preupload/v1") for p in posts)
    [commit] = _commits(hub)
    assert commit.path.startswith("/api/datasets/someone/wkr/commit/v1")
    assert commit.headers.get("authorization") == "Bearer hf_local_test_token"
    [files] = hub.state.commits.values()
    local = {p.relative_to(export).as_posix(): p.read_bytes() for p in export.rglob("*") if p.is_file()}
    assert files == local and "README.md" in files and "data/train-00000-of-00001.parquet" in files


def test_push_of_a_run_exports_it_first(run, hub):
    info = push(str(run), "someone/from-run")
    [files] = hub.state.commits.values()
    assert info.oid in hub.state.commits and "README.md" in files
    assert open_source(str(run))[0].sha256.encode() in files["README.md"]


@pytest.mark.parametrize("case", ["offline", "no_token", "unreachable", "refused"])
def test_push_fails_in_one_line_and_publishes_nothing(run, hub, monkeypatch, tmp_path, capsys, case):
    import huggingface_hub.constants as hf_constants

    if case == "offline":
        monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    elif case == "no_token":
        monkeypatch.delenv("HF_TOKEN")
        monkeypatch.delenv("HUGGING_FACE_HUB_TOKEN", raising=False)
        monkeypatch.setattr(hf_constants, "HF_TOKEN_PATH", str(tmp_path / "no-token"))
    elif case == "unreachable":
        with socket.socket() as sock:   # a port nobody listens on
            sock.bind(("127.0.0.1", 0))
            port = sock.getsockname()[1]
        monkeypatch.setenv("HF_ENDPOINT", f"http://127.0.0.1:{port}")
    else:
        hub.state.fail_commit = True
    rc = main(["memory", "push", str(run), "someone/wkr"])
    err = capsys.readouterr().err
    assert rc == 2 and "nothing was published" in err and len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    assert not hub.state.commits
    if case in ("offline", "no_token"):
        assert hub.state.requests == []   # refused before any request
    with pytest.raises(PublishError):
        push(str(run), "someone/wkr")


def _download(server: RecordingHub, repo_id: str, cache: Path, monkeypatch) -> None:
    """Fill a Hub cache the way huggingface_hub does: hf_hub_download of every committed file."""
    from huggingface_hub import hf_hub_download

    [files] = server.state.commits.values()
    for name in files:
        hf_hub_download(repo_id, name, repo_type="dataset", cache_dir=cache, endpoint=server.url)


def test_hub_cache_entry_reads_offline_like_the_run(run, hub, tmp_path, monkeypatch, capsys):
    push(str(run), "someone/wkr")
    cache = tmp_path / "hf" / "hub"
    _download(hub, "someone/wkr", cache, monkeypatch)
    assert (cache / "datasets--someone--wkr" / "refs" / "main").is_file()
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_CACHE", str(cache))
    from_hub, _ = open_source("hub:someone/wkr")
    from_run, _ = open_source(str(run))
    assert from_hub.kind == "hub" and from_hub.sha256 == from_run.sha256
    assert from_hub.provenance["run_id"] == "run" and from_hub.provenance["planner"]["model_id"] == "seeded-random"
    [commit] = hub.state.commits
    assert open_source(f"hub:someone/wkr@{commit}")[0].sha256 == from_run.sha256
    with pytest.raises(FileNotFoundError, match="not in the local Hub cache"):
        open_source("hub:someone/absent")
    # a run seeded from the Hub cache entry is the same stream, with the same episodes, as one seeded
    # from the run folder (same run id: the folder name is part of each entry's provenance)
    outs = {}
    for name, value in (("hub", "hub:someone/wkr"), ("run", str(run))):
        out = tmp_path / name / "t"
        assert main([*BASE[:-6], "--suite-size", "3", "--planner", "random:seeded-random", "--progress", "lines",
                     "--out", str(out), "--memory-from", value]) == 0
        [stream] = (out / "streams").iterdir()
        outs[name] = (stream.name, _episodes(stream / "episodes.jsonl"))
    assert outs["hub"] == outs["run"]
    sources = json.loads((tmp_path / "hub" / "t" / "manifest.json").read_text())["memory_sources"]
    [facts] = sources.values()
    assert facts["kind"] == "hub" and facts["sha256"] == from_run.sha256 and facts["path"].startswith(str(cache))


def _episodes(path: Path) -> list[dict[str, Any]]:
    def strip(obj: Any) -> Any:
        if isinstance(obj, dict):
            return {k: strip(v) for k, v in obj.items() if not any(t in k for t in ("latency", "seconds", "_ms"))}
        return [strip(v) for v in obj] if isinstance(obj, list) else obj

    return [strip(json.loads(line)) for line in path.read_text().splitlines()]
