"""Headless Chromium driven over the DevTools protocol (CDP): a page is opened, JavaScript
evaluated in it, a screenshot taken. The websocket is tornado's client (Bokeh's server runs
on tornado, so no new dependency)."""

import asyncio
import base64
import itertools
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

from tests.bench.live import stop_process

#: Chromium as root in a container: no sandbox, no GPU, nothing fetched from the network.
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--window-size=1300,1060",
    "--remote-debugging-port=0",
]


def chromium_binary() -> str | None:
    """The Chromium executable, if installed (Debian: /usr/bin/chromium)."""
    return shutil.which("chromium") or shutil.which("chromium-browser")


class Chromium:
    """A headless Chromium with a fresh profile; one page target, driven by :meth:`call`."""

    def __init__(self, binary: str, timeout: float = 120.0):
        self.profile = tempfile.TemporaryDirectory(prefix="circuitsim-chromium-")
        self.process = subprocess.Popen(
            [binary, *FLAGS, f"--user-data-dir={self.profile.name}", "about:blank"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,  # its helper processes in one group, stopped together
        )
        port_file = Path(self.profile.name) / "DevToolsActivePort"
        deadline = time.monotonic() + timeout
        while not (port_file.exists() and port_file.read_text().strip()):
            if time.monotonic() > deadline or self.process.poll() is not None:
                self.close()
                raise RuntimeError("chromium did not open its DevTools port")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=30) as answer:
            targets = json.loads(answer.read())
        page = next(t for t in targets if t["type"] == "page")
        self.loop = asyncio.new_event_loop()
        self.ids = itertools.count(1)
        self.socket = self.loop.run_until_complete(self._connect(page["webSocketDebuggerUrl"]))

    async def _connect(self, url: str):
        from tornado.websocket import websocket_connect

        return await websocket_connect(url, max_message_size=64 * 2**20)

    async def _call(self, method: str, params: dict) -> dict:
        key = next(self.ids)
        await self.socket.write_message(json.dumps({"id": key, "method": method, "params": params}))
        while True:
            message = await self.socket.read_message()
            if message is None:
                raise RuntimeError("chromium closed the DevTools connection")
            data = json.loads(message)
            if data.get("id") == key:
                if "error" in data:
                    raise RuntimeError(f"{method}: {data['error']}")
                return data["result"]

    def call(self, method: str, **params) -> dict:
        """One CDP command's result."""
        return self.loop.run_until_complete(asyncio.wait_for(self._call(method, params), 120))

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (JSON-serializable)."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression[:60]}...: {result['exceptionDetails']}")
        return result["result"].get("value")

    def screenshot(self, path: Path) -> None:
        """A PNG of the page as shown."""
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path.write_bytes(base64.b64decode(data))

    def close(self) -> None:
        if getattr(self, "socket", None) is not None:
            self.socket.close()
        if getattr(self, "loop", None) is not None:
            self.loop.close()
        stop_process(self.process)
        # Chromium's helpers (renderer, utility, crash handler) can outlive the browser for
        # a moment and write into the profile while it is removed ("Directory not empty:
        # 'Default'", seen in CI): stop the whole group, then remove the profile, retrying
        # briefly while a helper's last write lands.
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        for attempt in range(10):
            try:
                shutil.rmtree(self.profile.name)
                break
            except FileNotFoundError:
                break
            except OSError:
                if attempt == 9:
                    raise
                time.sleep(0.2)
        self.profile.cleanup()  # nothing left: marks the folder done
