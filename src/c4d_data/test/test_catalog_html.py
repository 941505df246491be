"""The catalog's HTML index in a real browser (Debian's headless chromium, driven over the
DevTools protocol on a pipe: no network, no extra package): no script error, no failed load, no
console error, every image decoded, report links that exist, header clicks that sort; and every
flight report's "Flight summary" figures equal its catalog row (the same numbers, full precision).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import sqlite3
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

from c4d_data.analysis.report import write_report
from c4d_data.analysis.summary import FIGURE_LABELS
from c4d_data.catalog import main as catalog
from c4d_data.catalog_synthetic import fleet_specs, write_flight

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
PROBLEMS = ("Runtime.exceptionThrown", "Network.loadingFailed")


class Browser:
    """Headless chromium with --remote-debugging-pipe (commands on fd 3, events on fd 4)."""

    def __init__(self, timeout: float = 30.0) -> None:
        self.profile = tempfile.mkdtemp(prefix="c4d-chromium-")
        cmd_r, self.cmd_w = os.pipe()
        self.resp_r, resp_w = os.pipe()

        def child() -> None:
            os.dup2(cmd_r, 3)
            os.dup2(resp_w, 4)

        self.proc = subprocess.Popen([CHROMIUM, *FLAGS, f"--user-data-dir={self.profile}", "--remote-debugging-pipe",
                                      "about:blank"], preexec_fn=child, pass_fds=(3, 4),
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        os.close(cmd_r)
        os.close(resp_w)
        self.timeout, self.buffer, self.next_id, self.events = timeout, b"", 0, []
        self.session: str | None = None
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        for domain in ("Runtime", "Log", "Network", "Page"):
            self.call(f"{domain}.enable")

    def _read(self) -> dict[str, Any]:
        deadline = time.monotonic() + self.timeout
        while b"\0" not in self.buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("chromium did not answer")
            chunk = os.read(self.resp_r, 1 << 16)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self.buffer += chunk
        raw, self.buffer = self.buffer.split(b"\0", 1)
        message = json.loads(raw)
        self.events.append(message)
        return message

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        message: dict[str, Any] = {"id": self.next_id, "method": method, "params": params}
        if self.session:
            message["sessionId"] = self.session
        os.write(self.cmd_w, json.dumps(message).encode() + b"\0")
        while True:
            answer = self._read()
            if answer.get("id") == self.next_id:
                assert "error" not in answer, answer
                return answer.get("result", {})

    def open(self, path: Path) -> list[dict[str, Any]]:
        """Load a file; returns the problems seen (exceptions, failed loads, console errors)."""
        self.events = []
        self.call("Page.navigate", url=path.as_uri())
        while not any(e.get("method") == "Page.loadEventFired" for e in self.events):
            self._read()
        self.eval("new Promise(r => setTimeout(r, 200))")  # late script errors
        return [e for e in self.events if e.get("method") in PROBLEMS or (
            e.get("method") == "Log.entryAdded" and e["params"]["entry"]["level"] == "error") or (
            e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] in ("error", "assert"))]

    def eval(self, expression: str) -> Any:
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        assert "exceptionDetails" not in result, result
        return result["result"].get("value")

    def close(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)  # chromium's own children (zygote, renderers) too
        except ProcessLookupError:
            pass
        self.proc.wait()
        os.close(self.cmd_w)
        os.close(self.resp_r)
        shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture(scope="module")
def browser():
    if not os.access(CHROMIUM, os.X_OK):
        pytest.fail(f"{CHROMIUM} missing: ./setup.sh installs Debian's chromium (apt, as root)")
    b = Browser()
    yield b
    b.close()


def report_figures(index: Path) -> dict[str, str]:
    return dict(re.findall(r'data-figure="(\w+)" data-value="([^"]*)"', index.read_text()))


def test_index_opens_clean_and_matches_reports(tmp_path, browser, capsys):
    flights = tmp_path / "flights"
    flights.mkdir()
    for k, spec in enumerate(fleet_specs(6, duration_s=12.0, state_hz=20.0, bulk=False)):
        write_flight(flights / f"flight_{k}.mcap", spec)
    analysed = write_report(flights / "flight_0.mcap", flights / "flight_0_report", progress=False)  # as `analyze` does
    out = tmp_path / "html"
    assert catalog([str(flights), "--html", str(out), "-j", "2"]) == 0
    printed = capsys.readouterr()
    assert "(5 reports written)" in printed.out, printed  # the existing one is linked, not rewritten

    problems = browser.open(out / "index.html")
    assert problems == [], problems
    images = browser.eval("Array.from(document.images).map(i => [i.getAttribute('src'), i.complete && i.naturalWidth > 0])")
    assert len(images) == 4 and all(ok for _, ok in images), images
    links = browser.eval("Array.from(document.querySelectorAll('#flights a')).map(a => a.getAttribute('href'))")
    assert len(links) == 12 and all((out / link).resolve().is_file() for link in links), links
    assert (out / links[0]).resolve() == analysed.resolve()

    column = list(browser.eval("Array.from(document.querySelectorAll('#flights th')).map(h => h.textContent)")).index(
        "max altitude [m]")
    read = f"Array.from(document.querySelectorAll('#flights tbody tr')).map(r => parseFloat(r.cells[{column}].dataset.v))"
    browser.eval(f"document.querySelectorAll('#flights th')[{column}].click()")
    ascending = browser.eval(read)
    browser.eval(f"document.querySelectorAll('#flights th')[{column}].click()")
    descending = browser.eval(read)
    assert ascending == sorted(ascending) and descending == sorted(ascending, reverse=True) and ascending != descending

    con = sqlite3.connect(flights / "catalog.sqlite")
    con.row_factory = sqlite3.Row
    rows = con.execute("SELECT * FROM flights").fetchall()
    assert len(rows) == 6
    for row in rows:
        figures = report_figures(Path(row["report"]))
        assert set(figures) == set(FIGURE_LABELS), figures
        for key, text in figures.items():
            assert text == str(row[key] if row[key] is not None or key != "failsafe_actions" else ""), (key, row["file"])
    con.close()
    problems = browser.open(Path(rows[1]["report"]))
    assert problems == [], problems
    assert browser.eval("Array.from(document.images).every(i => i.complete && i.naturalWidth > 0)")


def test_a_missing_image_is_seen(tmp_path, browser):
    """The check above can fail: a page with a missing image and a script error is caught."""
    page = tmp_path / "bad.html"
    page.write_text("<html><body><img src='missing.png'><script>undefinedFunction()</script></body></html>")
    kinds = {e["method"] for e in browser.open(page)}
    assert {"Runtime.exceptionThrown", "Network.loadingFailed"} <= kinds
