"""A live ``circuitsim bench`` server for the API and browser tests, and HTTP helpers."""

import json
import os
import re
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

from circuitsim.solver.compiled import warm_up

ROOT = Path(__file__).resolve().parents[2]

#: Wall seconds a test waits for the server or for model time to pass (the machine may be
#: loaded; no test asserts a wall-clock figure).
PATIENCE = 240.0


def request(
    url: str, data=None, method: str | None = None, headers: dict | None = None
) -> tuple[int, object]:
    """(status, decoded JSON or text) of a GET, or of a POST of ``data`` (JSON-encoded unless
    bytes) as ``Content-Type: application/json`` (``headers`` add to or replace it)."""
    body = None
    if data is not None:
        body = data if isinstance(data, bytes) else json.dumps(data).encode()
    headers = {"Content-Type": "application/json", **(headers or {})}
    req = urllib.request.Request(
        url, data=body, method=method or ("POST" if body else "GET"), headers=headers
    )
    try:
        with urllib.request.urlopen(req, timeout=60) as answer:
            status, text = answer.status, answer.read().decode()
            kind = answer.headers.get("Content-Type", "")
    except urllib.error.HTTPError as error:
        status, text, kind = error.code, error.read().decode(), error.headers.get("Content-Type")
    return status, json.loads(text) if "json" in (kind or "") else text


def wait_for_model_time(base: str, t: float) -> dict:
    """Poll ``/api/state`` until the session has passed model time ``t`` (s)."""
    deadline = time.monotonic() + PATIENCE
    while time.monotonic() < deadline:
        _, state = request(base + "api/state")
        assert state["error"] is None, state["error"]
        if state["t"] >= t:
            return state
        time.sleep(0.2)
    raise AssertionError(f"the bench did not reach t = {t} s within {PATIENCE} s")


def run_until(base: str, t: float) -> dict:
    """Run the session to the first chunk boundary at or past model time ``t`` (s) and hold it
    there (``POST /api/run`` with ``until``): the test acts at a known model time, however
    fast or loaded the machine (a test that polls a clock running on acts wherever it catches
    it: unthrottled, hundreds of chunks past)."""
    status, state = request(base + "api/run", {"running": True, "until": t})
    assert status == 200, state
    deadline = time.monotonic() + PATIENCE
    while time.monotonic() < deadline:
        assert state["error"] is None, state["error"]
        if not state["running"] and state["until"] is None and state["t"] >= t - 1e-9:
            return state
        time.sleep(0.1)
        _, state = request(base + "api/state")
    raise AssertionError(f"the bench did not reach t = {t} s within {PATIENCE} s")


class BenchProcess:
    """``python -m circuitsim bench ...`` on a free port, until :meth:`stop`."""

    def __init__(self, *options: str):
        # the kernel the bench runs is made ready here first (compiled into the shared cache
        # if it is cold: minutes on a loaded machine, past PATIENCE), so that the bench's
        # first chunk loads it instead of compiling while the test waits for model time
        warm_up(("ports",))
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        # its log (a line per request) goes to a file: a pipe nobody reads while the test
        # runs fills at 64 KiB and then blocks the server mid-request
        self.log = tempfile.TemporaryFile(mode="w+")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "circuitsim", "bench", "--no-browser", "--port", "0",
             *options],
            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=self.log, text=True,
        )  # fmt: skip
        deadline = time.monotonic() + PATIENCE
        self.url = None
        while time.monotonic() < deadline and self.url is None:
            line = self.process.stdout.readline()
            if not line:
                raise AssertionError(f"bench exited: {self.stderr()}")
            found = re.search(r" at (http://\S+/) ", line)
            self.url = found.group(1) if found else None
        if self.url is None:
            self.stop()
            raise AssertionError("bench did not print its address")

    def stderr(self) -> str:
        """What the bench wrote to stderr so far (its progress, warnings and request log)."""
        self.log.seek(0)
        return self.log.read()

    def stop(self) -> None:
        stop_process(self.process)
        self.log.close()


def stop_process(process: subprocess.Popen) -> None:
    """Terminate a process this test started, killing it after 30 s."""
    process.terminate()
    try:
        process.wait(30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(30)
