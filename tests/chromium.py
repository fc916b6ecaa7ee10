"""Headless Chromium driven over its DevTools protocol (a pipe, no network, no extra package), for
the tests of the HTML pages: open a page, wait in real time until a script condition holds (not on
Chromium's virtual clock, which runs out while the page still inflates its data on a loaded
machine), run scripts, scroll, take screenshots, and collect the console's messages."""

from __future__ import annotations

import base64
import io
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)

#: messages that are the software GL's notes (reading pixels back), not the page's
_NOISE = ("GL Driver Message",)


def _on_fds_3_and_4(read: int, write: int) -> None:
    """(In the child, before exec) the pipe's ends on fds 3 and 4, inheritable."""
    read, write = os.dup(read), os.dup(write)  # above 4, whatever numbers they had
    os.dup2(read, 3)
    os.dup2(write, 4)


class Page:
    """One page in a fresh headless Chromium (``with Page(url, (width, height)) as p: ...``);
    ``console``: the page's console messages, errors and uncaught exceptions, in order."""

    def __init__(self, url: str, window: tuple[int, int] = (1000, 760), timeout: float = 120.0):
        self.url, self.window, self.timeout = url, window, timeout
        self.console: list[str] = []
        self._id, self._buf, self._session = 0, b"", None

    def __enter__(self) -> Page:
        self._profile = tempfile.TemporaryDirectory(prefix="hj-chromium-")
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        # Chromium reads the protocol on fd 3 and writes it on fd 4
        self._proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--hide-scrollbars", "--no-first-run", "--remote-debugging-pipe",
             f"--user-data-dir={self._profile.name}", f"--window-size={self.window[0]},{self.window[1]}", "about:blank"],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            close_fds=False, preexec_fn=lambda: _on_fds_3_and_4(to_browser_r, from_browser_w))
        os.close(to_browser_r)
        os.close(from_browser_w)
        target = self._call("Target.createTarget", url="about:blank", session=False)["targetId"]
        self._session = self._call("Target.attachToTarget", targetId=target, flatten=True, session=False)["sessionId"]
        for domain in ("Page", "Runtime", "Log"):
            self._call(f"{domain}.enable")
        self._call("Emulation.setDeviceMetricsOverride", width=self.window[0], height=self.window[1],
                   deviceScaleFactor=1, mobile=False)
        self._call("Page.navigate", url=self.url)
        return self

    def __exit__(self, *exc) -> None:
        try:
            self._send({"id": 0, "method": "Browser.close"})
            self._proc.wait(timeout=20)
        except Exception:  # noqa: BLE001 - a browser that will not close is killed
            self._proc.kill()
            self._proc.wait()
        os.close(self._to_browser)
        os.close(self._from_browser)
        self._profile.cleanup()

    def _send(self, message: dict) -> None:
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")

    def _receive(self, deadline: float) -> dict:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._from_browser], [], [], left)[0]:
                raise TimeoutError("Chromium did not answer")
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the pipe")
            self._buf += chunk
        message, self._buf = self._buf.split(b"\0", 1)
        return json.loads(message)

    def _event(self, m: dict) -> None:
        p = m.get("params", {})
        if m.get("method") == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            self.console.append(f"console.{p.get('type')}: {text}")
        elif m.get("method") == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            self.console.append(f"exception: {d.get('exception', {}).get('description') or d.get('text')}")
        elif m.get("method") == "Log.entryAdded":
            self.console.append(f"log.{p['entry'].get('level')}: {p['entry'].get('text')}")
        self.console = [c for c in self.console if not any(n in c for n in _NOISE)]

    def _call(self, method: str, session: bool = True, **params) -> dict:
        self._id += 1
        message = {"id": self._id, "method": method, "params": params}
        if session and self._session:
            message["sessionId"] = self._session
        self._send(message)
        deadline = time.monotonic() + self.timeout
        while True:
            m = self._receive(deadline)
            if m.get("id") == self._id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self._event(m)

    def run(self, expression: str):
        """The value of a script ``expression`` in the page (awaited when a promise)."""
        r = self._call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails'].get('text')}")
        return r["result"].get("value")

    def wait(self, expression: str, timeout: float | None = None) -> float:
        """Wait (real time) until ``expression`` is true in the page (an expression that throws, as
        while the page loads, is false); the seconds it took."""
        start = time.monotonic()
        while not self.run(f"(() => {{ try {{ return Boolean({expression}); }} catch {{ return false; }} }})()"):
            if time.monotonic() - start > (timeout or self.timeout):
                raise TimeoutError(f"the page never had {expression}")
            time.sleep(0.05)
        return time.monotonic() - start

    def drag(self, start: tuple[float, float], end: tuple[float, float], steps: int = 8) -> None:
        """A left-button mouse drag from ``start`` to ``end`` (window pixels)."""
        self._call("Input.dispatchMouseEvent", type="mouseMoved", x=start[0], y=start[1])
        self._call("Input.dispatchMouseEvent", type="mousePressed", x=start[0], y=start[1], button="left",
                   buttons=1, clickCount=1)
        for k in range(1, steps + 1):
            x = start[0] + (end[0] - start[0]) * k / steps
            y = start[1] + (end[1] - start[1]) * k / steps
            self._call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y, button="left", buttons=1)
        self._call("Input.dispatchMouseEvent", type="mouseReleased", x=end[0], y=end[1], button="left",
                   buttons=1, clickCount=1)

    def screenshot(self, path: str | os.PathLike | None = None) -> np.ndarray:
        """The window's picture (h, w, 3); saved as PNG at ``path`` where given."""
        from PIL import Image

        png = base64.b64decode(self._call("Page.captureScreenshot", format="png")["data"])
        if path is not None:
            Path(path).write_bytes(png)
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
