"""The episode viewer in a real headless browser (Debian's chromium), driven over the DevTools protocol
on a pipe (`--remote-debugging-pipe`: no port, no websocket client, no Python package needed).

Checks: the overview, a stream page and episode pages load with no console error or uncaught exception;
clicking a stream, an episode and "next" navigates; the arrow key goes back; screenshots are saved (to
the test's tmp folder, and to $WORLDMIND_SCREENSHOTS when set). Chromium is installed with apt-get when
missing; the test skips, saying why, only if that fails.
"""

from __future__ import annotations

import base64
import json
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from worldmind_local.cli import main

pytestmark = pytest.mark.slow


def _chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found:
        return found
    if os.geteuid() != 0:
        pytest.skip("chromium is not installed and this user cannot apt-get install it (not root)")
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for cmd in (["apt-get", "update", "-qq"], ["apt-get", "install", "-y", "-qq", "chromium", "chromium-driver"]):
        done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
        if done.returncode != 0 and cmd[1] == "install":
            pytest.skip(f"apt-get install chromium failed: {done.stderr.strip()[-400:]}")
    found = shutil.which("chromium")
    if not found:
        pytest.skip("apt-get installed no chromium binary")
    return found


class Browser:
    """Chromium with the DevTools protocol on fds 3 (commands in) and 4 (results out), NUL-delimited JSON."""

    def __init__(self, binary: str) -> None:
        self._profile = tempfile.mkdtemp(prefix="wm-chromium-")
        cmd_r, self._cmd_w = os.pipe()
        self._res_r, res_w = os.pipe()

        def child_fds() -> None:
            a, b = os.dup(cmd_r), os.dup(res_w)
            os.dup2(a, 3)
            os.dup2(b, 4)
            os.set_inheritable(3, True)
            os.set_inheritable(4, True)

        self.proc = subprocess.Popen(
            [binary, "--headless=new", "--remote-debugging-pipe", "--no-sandbox", "--disable-gpu",
             "--no-first-run", "--no-default-browser-check", "--disable-extensions", "--disable-dev-shm-usage",
             "--window-size=1280,900", f"--user-data-dir={self._profile}", "about:blank"],
            preexec_fn=child_fds, close_fds=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        os.close(cmd_r)
        os.close(res_w)
        self._next_id = 0
        self._messages: queue.Queue[dict[str, Any]] = queue.Queue()
        self.events: list[dict[str, Any]] = []
        threading.Thread(target=self._reader, daemon=True).start()
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Runtime", "Log", "Page"):
            self.call(f"{domain}.enable", session=True)

    def _reader(self) -> None:
        buf = b""
        while True:
            chunk = os.read(self._res_r, 65536)
            if not chunk:
                return
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                self._messages.put(json.loads(raw))

    def call(self, method: str, params: dict[str, Any] | None = None, *, session: bool = False,
             timeout: float = 30.0) -> dict[str, Any]:
        self._next_id += 1
        msg: dict[str, Any] = {"id": self._next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = self.session
        os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._messages.get(timeout=max(0.1, deadline - time.monotonic()))
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_event(self, name: str, timeout: float = 30.0) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        for i, event in enumerate(self.events):
            if event.get("method") == name:
                return self.events.pop(i)
        while time.monotonic() < deadline:
            try:
                event = self._messages.get(timeout=0.2)
            except queue.Empty:
                continue
            if event.get("method") == name:
                return event
            self.events.append(event)
        raise TimeoutError(name)

    def evaluate(self, expression: str) -> Any:
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=True)
        return result.get("result", {}).get("value")

    def settle(self, url_suffix: str, timeout: float = 20.0) -> str:
        """Wait until the page at `url_suffix` has loaded and its script ran."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            href = self.evaluate("location.href + '|' + document.readyState + '|' + "
                                 "(document.documentElement.dataset.viewer || '')")
            if href and href.split("|")[0].endswith(url_suffix) and href.endswith("|complete|ready"):
                return href.split("|")[0]
            time.sleep(0.1)
        raise TimeoutError(f"page {url_suffix} did not load: {self.evaluate('location.href')}")

    def goto(self, url: str) -> None:
        self.call("Page.navigate", {"url": url}, session=True)
        self.settle(url.rsplit("/", 1)[-1])

    def click(self, selector: str) -> None:
        assert self.evaluate(f"(() => {{ const a = document.querySelector({json.dumps(selector)}); "
                             f"if (!a) return false; a.click(); return true; }})()"), selector

    def key(self, key: str, code: int) -> None:
        for kind in ("keyDown", "keyUp"):
            self.call("Input.dispatchKeyEvent", {"type": kind, "key": key, "code": key,
                                                 "windowsVirtualKeyCode": code}, session=True)

    def screenshot(self, path: Path) -> Path:
        data = self.call("Page.captureScreenshot", {"format": "png"}, session=True)["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions and failed loads seen so far."""
        try:
            while True:
                self.events.append(self._messages.get_nowait())
        except queue.Empty:
            pass
        out = []
        for e in self.events:
            method, params = e.get("method"), e.get("params", {})
            if method == "Runtime.exceptionThrown":
                out.append(f"exception: {params.get('exceptionDetails', {}).get('text')}")
            elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
                out.append(f"console.{params.get('type')}: {params.get('args')}")
            elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
                out.append(f"log: {params['entry'].get('text')} {params['entry'].get('url', '')}")
        return out

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=5)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        os.close(self._cmd_w)
        shutil.rmtree(self._profile, ignore_errors=True)


@pytest.fixture(scope="module")
def site(real_runs, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("viewer")
    runs = [str(real_runs[k]) for k in ("runA", "runB", "runC")]
    assert main(["report", *runs, "--format", "html", "--out", str(out)]) == 0
    return out / "site"


@pytest.fixture(scope="module")
def browser():
    b = Browser(_chromium())
    yield b
    b.close()


def _keep(path: Path) -> None:
    target = os.environ.get("WORLDMIND_SCREENSHOTS")
    if target:
        Path(target).mkdir(parents=True, exist_ok=True)
        shutil.copy(path, Path(target) / path.name)


def test_viewer_loads_navigates_and_has_no_console_errors(site: Path, browser: Browser, tmp_path: Path) -> None:
    browser.goto((site / "index.html").as_uri())
    assert browser.evaluate("document.querySelectorAll('section.table').length") >= 8
    assert browser.evaluate("Array.from(document.images).every(i => i.complete && i.naturalWidth > 0)")
    _keep(browser.screenshot(tmp_path / "viewer-index.png"))

    # overview -> a WorldMind stream -> its first episode
    stream_link = browser.evaluate(
        "Array.from(document.querySelectorAll('#streams-list a')).find(a => a.textContent.includes('base.worldmind')"
        " && !a.textContent.includes('.s0.')).getAttribute('href')")
    browser.click(f'#streams-list a[href="{stream_link}"]')
    browser.settle(stream_link)
    assert browser.evaluate("document.querySelectorAll('#episodes tbody tr').length") == 3
    browser.click("#episodes tbody tr a")
    first = browser.settle("-e0.html")
    assert browser.evaluate("document.getElementById('instruction').textContent.length") > 10
    assert browser.evaluate("document.querySelectorAll('details[id^=call-]').length") >= 1
    assert "system" in browser.evaluate("document.querySelector('details[id^=call-]').textContent")  # the prompt

    # next episode by the link, back by the arrow key
    browser.click("#next")
    browser.settle("-e1.html")
    _keep(browser.screenshot(tmp_path / "viewer-episode.png"))
    browser.key("ArrowLeft", 37)
    assert browser.settle("-e0.html") == first

    assert browser.errors() == []
    assert (tmp_path / "viewer-index.png").stat().st_size > 10_000
    assert (tmp_path / "viewer-episode.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
