"""Run folders under concurrency and damage (issue 18, points 1 and 3): one owner at a time, a stale
lock taken over, and a damaged episodes line quarantined without losing any intact record."""

from __future__ import annotations

import json
import logging
import os
import signal
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from worldmind_local.runner.artifacts import LOCK_FILENAME, RunDir, RunFolderBusy, RunLock, read_holder

ROOT = Path(__file__).resolve().parents[3]


def _snapshot(folder: Path) -> dict[str, tuple[int, bytes]]:
    return {str(p.relative_to(folder)): (p.stat().st_mtime_ns, p.read_bytes())
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _python(code: str, *args: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code), *args], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


SECOND = """
    import sys
    from worldmind_local.runner.artifacts import RunDir, RunFolderBusy
    try:
        with RunDir(sys.argv[1]).lock():
            print("acquired")
    except RunFolderBusy as exc:
        print(exc)
        sys.exit(3)
"""


def test_a_second_process_gets_one_line_naming_the_holder_and_changes_nothing(tmp_path: Path) -> None:
    run = RunDir(tmp_path / "run")
    with run.lock():
        run.open({"a": 1}, {"started_at": "t0"})
        before = _snapshot(run.root)
        proc = _python(SECOND, str(run.root))
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 3, err
        lines = out.strip().splitlines()
        assert len(lines) == 1
        assert f"pid {os.getpid()}" in lines[0] and socket.gethostname() in lines[0] and "since" in lines[0]
        assert _snapshot(run.root) == before
    assert not (run.root / LOCK_FILENAME).exists()  # released cleanly
    proc = _python(SECOND, str(run.root))
    assert proc.communicate(timeout=60)[0].strip() == "acquired" and proc.returncode == 0


def test_a_lock_in_this_process_also_refuses_a_second_owner(tmp_path: Path) -> None:
    with RunLock(tmp_path) as first:
        assert first.held and read_holder(tmp_path)["pid"] == os.getpid()
        with pytest.raises(RunFolderBusy, match="in use by pid"):
            RunLock(tmp_path).acquire()
    with RunLock(tmp_path):
        pass


def test_the_lock_of_a_killed_process_is_taken_over(tmp_path: Path) -> None:
    proc = _python("""
        import sys, time
        from worldmind_local.runner.artifacts import RunLock
        RunLock(sys.argv[1]).acquire()
        print("locked", flush=True)
        time.sleep(120)
    """, str(tmp_path))
    assert proc.stdout.readline().strip() == "locked"
    with pytest.raises(RunFolderBusy, match=f"pid {proc.pid}"):
        RunLock(tmp_path).acquire()
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert read_holder(tmp_path)["pid"] == proc.pid  # the dead holder's record is still there
    with RunLock(tmp_path):
        assert read_holder(tmp_path)["pid"] == os.getpid()


def test_a_lock_kept_by_a_dead_holders_descriptor_is_broken(tmp_path: Path) -> None:
    """A forked worker of a dead run still holds the flock; the recorded holder pid is dead."""
    import fcntl

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    fd = os.open(tmp_path / LOCK_FILENAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.write(fd, json.dumps({"pid": int(dead.stdout), "host": socket.gethostname(),
                                 "started_at": "earlier"}).encode())
        with RunLock(tmp_path) as lock:
            assert lock.held and read_holder(tmp_path)["pid"] == os.getpid()
    finally:
        os.close(fd)


def test_a_held_lock_with_an_alive_or_foreign_holder_is_not_broken(tmp_path: Path) -> None:
    import fcntl

    fd = os.open(tmp_path / LOCK_FILENAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.write(fd, json.dumps({"pid": 1, "host": "elsewhere", "started_at": "t"}).encode())
        with pytest.raises(RunFolderBusy, match="on host elsewhere"):
            RunLock(tmp_path).acquire()
    finally:
        os.close(fd)


# -- episodes.jsonl: quarantine, torn tail, waves ---------------------------------------------------


def _lines(stream) -> list[int]:
    return [json.loads(x)["index"] for x in stream.episodes_path.read_text().splitlines()]


@pytest.mark.parametrize("damage", [b'{"index": 1, "succ\n', b'\xff\xfe{"index": 1}\n', b'[1, 2]\n', b'"text"\n',
                                    b'{"index": ' + b"9" * 5000 + b"}\n", b"[" * 100_000 + b"\n"])
def test_a_damaged_middle_line_is_quarantined_and_every_intact_record_kept(tmp_path: Path, damage: bytes,
                                                                          caplog) -> None:
    sd = RunDir(tmp_path).stream("s")
    sd.ensure()
    sd.append_episode({"index": 0})
    with sd.episodes_path.open("ab") as f:
        f.write(damage)
    sd.append_episodes([{"index": 2}, {"index": 3}])
    with caplog.at_level(logging.WARNING, logger="worldmind_local.runner.artifacts"):
        records = sd.read_episodes()
    assert [r["index"] for r in records] == [0, 2, 3]
    assert _lines(sd) == [0, 2, 3]
    quarantined = [json.loads(x) for x in sd.quarantine_path.read_text().splitlines()]
    assert len(quarantined) == 1 and quarantined[0]["line"] == 2 and quarantined[0]["error"]
    assert quarantined[0]["raw"] == damage.decode("utf-8", "replace").rstrip("\n")
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "line 2" in warnings[0] and "quarantine" in warnings[0]
    assert "\n" not in warnings[0]
    assert sd.read_episodes() == records  # idempotent: nothing more to move


def test_a_torn_last_line_is_cut_even_after_a_quarantine(tmp_path: Path) -> None:
    sd = RunDir(tmp_path).stream("s")
    sd.ensure()
    sd.append_episodes([{"index": 0}, {"index": 1}])
    with sd.episodes_path.open("ab") as f:
        f.write(b"garbage\n")
        f.write(b'{"index": 3}\n{"index": 4, "to')
    assert [r["index"] for r in sd.read_episodes()] == [0, 1, 3]
    assert sd.episodes_path.read_bytes().endswith(b'{"index": 3}\n')
    sd.append_episode({"index": 4})
    assert _lines(sd) == [0, 1, 3, 4]


def test_a_torn_last_line_alone_is_truncated_without_quarantine(tmp_path: Path) -> None:
    sd = RunDir(tmp_path).stream("s")
    sd.ensure()
    sd.append_episode({"index": 0})
    with sd.episodes_path.open("ab") as f:
        f.write(b'{"index": 1')
    assert [r["index"] for r in sd.read_episodes()] == [0]
    assert sd.episodes_path.read_bytes() == b'{"index": 0}\n' and not sd.quarantine_path.exists()


def test_append_episodes_appends_a_wave_in_order(tmp_path: Path) -> None:
    sd = RunDir(tmp_path).stream("s")
    sd.ensure()
    sd.append_episodes([])
    assert not sd.episodes_path.exists() or sd.episodes_path.read_bytes() == b""
    sd.append_episodes([{"index": i, "text": "é"} for i in range(3)])
    assert _lines(sd) == [0, 1, 2]
    assert [r["text"] for r in sd.read_episodes()] == ["é"] * 3
