"""Headless Chromium over the DevTools protocol: open a page, evaluate script, take screenshots.

Used to check the replay pages in a real browser, to measure their frame rate and to take
the gallery's screenshots. Needs a Chromium executable (``chromium``, found on ``PATH``,
or passed explicitly) and the ``websocket-client`` package (in the ``test`` extra).

>>> with HeadlessChromium() as browser:                     # doctest: +SKIP
...     page = browser.open("file:///tmp/replay.html#frame=10")
...     page.wait_for("document.body.dataset.ready === '1'")
...     png = page.screenshot()
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any, Self

from ...core.errors import RobofleetError
from ...core.files import write_bytes

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "chrome")
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--disable-extensions", "--hide-scrollbars", "--mute-audio", "--remote-debugging-port=0")


class BrowserError(RobofleetError, RuntimeError):
    """Chromium is missing, did not start, or a page did not do what was asked in time."""


def find_chromium() -> str | None:
    """The path of a Chromium executable on ``PATH`` (or ``$ROBOFLEET_CHROMIUM``), or ``None``."""
    explicit = os.environ.get("ROBOFLEET_CHROMIUM")
    if explicit:
        return explicit if Path(explicit).is_file() else None
    return next((p for p in map(shutil.which, CHROMIUM_NAMES) if p), None)


class HeadlessChromium:
    """A headless Chromium process of its own (fresh profile), driven over one websocket.

    Parameters
    ----------
    executable:
        The browser (default: :func:`find_chromium`).
    width, height:
        The window size pages get, in CSS pixels (device scale factor 1).
    timeout:
        Seconds to wait for the browser and for each command.
    """

    def __init__(self, executable: str | None = None, width: int = 1280, height: int = 800, timeout: float = 30.0):
        try:
            import websocket  # noqa: F401  (websocket-client)
        except ImportError:
            raise BrowserError("HeadlessChromium: expected the websocket-client package (pip install 'robofleet[test]'), "
                               "received an environment without it") from None
        self.executable = executable or find_chromium()
        if not self.executable:
            raise BrowserError(f"HeadlessChromium: expected a Chromium executable ({', '.join(CHROMIUM_NAMES)}) on PATH, received none")
        self.width, self.height, self.timeout = width, height, timeout
        self.profile = tempfile.mkdtemp(prefix="robofleet-chromium-")
        self.process: subprocess.Popen | None = None
        self.socket = None
        self.ids = itertools.count(1)
        self.pages: dict[str, Page] = {}

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Launch the browser and connect to it."""
        import websocket

        args = [self.executable, *CHROMIUM_FLAGS, f"--user-data-dir={self.profile}", f"--window-size={self.width},{self.height}", "about:blank"]
        self.process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        endpoint = self._endpoint()
        self.socket = websocket.create_connection(endpoint, timeout=self.timeout, suppress_origin=True)

    def _endpoint(self) -> str:
        """The browser's websocket address, read from its stderr."""
        deadline = time.monotonic() + self.timeout
        seen = []
        assert self.process is not None and self.process.stderr is not None
        while time.monotonic() < deadline:
            line = self.process.stderr.readline()
            if not line and self.process.poll() is not None:
                break
            seen.append(line.strip())
            match = re.search(r"DevTools listening on (ws://\S+)", line)
            if match:
                return match.group(1)
        self.close()
        raise BrowserError(f"{self.executable}: expected 'DevTools listening on ws://…' on stderr, received {seen[-3:]!r}")

    def close(self) -> None:
        """Stop the browser this object started and remove its profile."""
        if self.socket is not None:
            try:
                self.socket.close()
            except OSError:
                pass
            self.socket = None
        if self.process is not None:
            if self.process.poll() is None:
                self.process.terminate()
                try:
                    self.process.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.process.kill()
                    self.process.wait(timeout=10)
            if self.process.stderr is not None:
                self.process.stderr.close()
            self.process = None
        shutil.rmtree(self.profile, ignore_errors=True)

    # -- the protocol ---------------------------------------------------------------------
    def send(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
        """Send one command and return its result; events that arrive meanwhile go to their page."""
        if self.socket is None:
            raise BrowserError("HeadlessChromium: expected a started browser, received a closed one")
        ident = next(self.ids)
        message = {"id": ident, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        self.socket.send(json.dumps(message))
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            reply = json.loads(self.socket.recv())
            if reply.get("id") == ident:
                if "error" in reply:
                    raise BrowserError(f"{method}: expected a result, received {reply['error']}")
                return reply.get("result", {})
            self._dispatch(reply)
        raise BrowserError(f"{method}: expected an answer within {self.timeout} s, received none")

    def _dispatch(self, event: dict[str, Any]) -> None:
        page = self.pages.get(event.get("sessionId", ""))
        if page is not None:
            page.on_event(event.get("method", ""), event.get("params", {}))

    def open(self, url: str) -> Page:
        """A new tab showing ``url`` (loaded when this returns), its console watched."""
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        page = Page(self, session, target)
        self.pages[session] = page
        for domain in ("Page", "Runtime", "Log"):
            self.send(f"{domain}.enable", session=session)
        self.send("Emulation.setDeviceMetricsOverride", {"width": self.width, "height": self.height, "deviceScaleFactor": 1,
                                                         "mobile": False}, session=session)
        page.navigate(url)
        return page


class Page:
    """One tab: navigate, evaluate, wait for a condition, screenshot; ``errors`` collects
    console errors and uncaught exceptions."""

    def __init__(self, browser: HeadlessChromium, session: str, target: str):
        self.browser, self.session, self.target = browser, session, target
        self.errors: list[str] = []
        self.loaded = False

    def on_event(self, method: str, params: dict[str, Any]) -> None:
        if method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            self.errors.append(str(details.get("exception", {}).get("description") or details.get("text")))
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            self.errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in params.get("args", [])))
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            self.errors.append(str(params["entry"].get("text")))
        elif method == "Page.loadEventFired":
            self.loaded = True

    def send(self, method: str, params: dict[str, Any] | None = None) -> dict[str, Any]:
        return self.browser.send(method, params, self.session)

    def navigate(self, url: str) -> None:
        """Go to ``url`` and wait for its load event."""
        self.loaded = False
        self.send("Page.navigate", {"url": url})
        self.wait_for("document.readyState === 'complete'")

    def evaluate(self, expression: str, await_promise: bool = False) -> Any:
        """The value of a script expression (JSON-serialisable), or :class:`BrowserError` if it threw."""
        result = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": await_promise})
        if "exceptionDetails" in result:
            raise BrowserError(f"{expression[:60]}: expected a value, received {result['exceptionDetails'].get('text')}")
        return result.get("result", {}).get("value")

    def wait_for(self, expression: str, timeout: float | None = None) -> Any:
        """Poll ``expression`` until it is truthy; return its value."""
        deadline = time.monotonic() + (timeout or self.browser.timeout)
        while time.monotonic() < deadline:
            value = self.evaluate(expression)
            if value:
                return value
            time.sleep(0.05)
        raise BrowserError(f"{expression}: expected it to become true within {timeout or self.browser.timeout} s, received "
                           f"false; page errors: {self.errors[:3]}")

    def bring_to_front(self) -> None:
        """Make this the visible tab (hidden tabs get no animation frames, so they do not draw)."""
        self.send("Page.bringToFront")

    def screenshot(self) -> bytes:
        """PNG of the viewport."""
        return base64.b64decode(self.send("Page.captureScreenshot", {"format": "png"})["data"])

    def close(self) -> None:
        self.browser.send("Target.closeTarget", {"targetId": self.target})
        self.browser.pages.pop(self.session, None)


def screenshot_page(html_path: str | Path, png_path: str | Path, *, frame: int | None = None, width: int = 1280,
                    height: int = 800) -> Path:
    """Open a replay page headless at ``frame`` (default: the last) and save a PNG of it."""
    html_path, png_path = Path(html_path).resolve(), Path(png_path)
    with HeadlessChromium(width=width, height=height) as browser:
        page = browser.open(html_path.as_uri())
        page.wait_for("document.body.dataset.ready === '1'")
        last = int(page.evaluate("Number(document.body.dataset.nFrames)")) - 1
        page.evaluate(f"location.hash = 'frame={last if frame is None else int(frame)}'")
        page.wait_for(f"document.body.dataset.frame === '{last if frame is None else int(frame)}'")
        time.sleep(0.2)
        write_bytes(png_path, page.screenshot())
    return png_path
