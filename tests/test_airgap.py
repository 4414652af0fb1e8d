"""Air-gapped by test (issue 18, point 10): a whole small run and a real (tiny) model make no network
connection other than to loopback or a URL the user configured.

The check is a Python audit hook (`sys.addaudithook`) on the socket events; audit hooks cannot be
removed, so it runs in a subprocess. The hook refuses (raises) and records any other destination, so a
library that swallows the error still fails the test. The subprocess does not inherit the test
session's HF_*_OFFLINE settings: the suite must go offline on its own.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

GUARD = textwrap.dedent('''
    import ipaddress, json, os, sys

    ALLOWED = {h for h in os.environ.get("AIRGAP_ALLOWED_HOSTS", "").split(",") if h}
    violations = []

    def _allowed(host):
        if host in (None, "", "localhost", "localhost.localdomain") or host in ALLOWED:
            return True
        if isinstance(host, bytes):
            host = host.decode(errors="replace")
        try:
            return ipaddress.ip_address(str(host).split("%")[0]).is_loopback
        except ValueError:
            return False

    def hook(event, args):
        if event in ("socket.connect", "socket.sendto"):
            address = args[1]
            if not isinstance(address, tuple):  # AF_UNIX path or similar: local by nature
                return
            host = address[0]
        elif event in ("socket.getaddrinfo", "socket.gethostbyname", "socket.gethostbyaddr"):
            host = args[0]
        else:
            return
        if not _allowed(host):
            violations.append(f"{event} -> {host!r}")
            raise ConnectionRefusedError(f"air-gap test: {event} to {host!r} refused")

    sys.addaudithook(hook)

    def report(phase, rc):
        print("AIRGAP " + json.dumps({"phase": phase, "rc": rc, "violations": violations}), flush=True)
''')

RUN = GUARD + textwrap.dedent('''
    from worldmind_local.cli import main
    rc = main(["run", "--planner", "random:seeded-random", "--benchmark", "eb_navigation", "--limit", "1",
               "--suite", "generated", "--subsets", "base", "--out", sys.argv[1], "--progress", "lines"])
    report("run", rc)

    import asyncio
    from models.base import ChatRequest, Sampling
    from models.specs import make_backend
    backend = make_backend("hf:tiny-qwen3")
    request = ChatRequest(messages=[{"role": "user", "content": "Open the fridge."}],
                          sampling=Sampling(max_tokens=4))
    results = asyncio.run(backend.complete([request]))
    asyncio.run(backend.aclose())
    report("hf:tiny-qwen3", 0 if results and isinstance(results[0].text, str) else 1)
''')


def _clean_env() -> dict[str, str]:
    drop = {"HF_HUB_OFFLINE", "TRANSFORMERS_OFFLINE", "HF_DATASETS_OFFLINE"}
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env["AIRGAP_ALLOWED_HOSTS"] = ""
    return env


def test_a_small_run_and_a_tiny_model_touch_no_network(tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-c", RUN, str(tmp_path / "run")], cwd=ROOT, env=_clean_env(),
                          capture_output=True, text=True, timeout=600)
    reports = [json.loads(line[len("AIRGAP "):]) for line in done.stdout.splitlines() if line.startswith("AIRGAP ")]
    assert done.returncode == 0 and len(reports) == 2, (done.stdout[-2000:], done.stderr[-4000:])
    for report in reports:
        assert report["violations"] == [], report
        assert report["rc"] == 0, (report, done.stderr[-4000:])
    assert (tmp_path / "run" / "results.json").is_file()


def test_the_guard_refuses_a_foreign_destination_and_allows_loopback() -> None:
    """The hook itself works: loopback passes, anything else is refused and recorded (no traffic:
    the refusal happens before the connect)."""
    probe = GUARD + textwrap.dedent('''
        import socket
        server = socket.socket(); server.bind(("127.0.0.1", 0)); server.listen(1)
        socket.create_connection(server.getsockname(), timeout=5).close()
        for target in (("192.0.2.1", 80), ("example.invalid", 443)):
            try:
                socket.create_connection(target, timeout=1)
            except OSError:
                pass
        report("probe", 0)
    ''')
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=_clean_env(), capture_output=True,
                          text=True, timeout=120)
    line = next(x for x in done.stdout.splitlines() if x.startswith("AIRGAP "))
    violations = json.loads(line[len("AIRGAP "):])["violations"]
    assert any("192.0.2.1" in v for v in violations) and any("example.invalid" in v for v in violations)
    assert not any("127.0.0.1" in v for v in violations)
