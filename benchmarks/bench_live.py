"""The live bench's figures (docs/bench.md): the rate the machine sustains, the lag between a
knob change and its effect, and the session-vs-ODE NRMSD.

    python benchmarks/bench_live.py [--seconds 10] [--changes 10]

- rate: a library session (no server) stepped as fast as it runs, the wheelset at 57 m/s from
  a 5 mm push, flange off, no forcing: model seconds per wall second, per chunk length;
- NRMSD: that session's circuit trace against the ODE solved here with mechanics.solve;
- lag: ``circuitsim bench --rate 1`` in a subprocess; the speed knob is turned (54 <-> 57 m/s)
  through ``POST /api/knobs`` and ``GET /api/state`` polled every 10 ms until the first chunk
  with the new value has been computed (model time past ``t_applied`` + one chunk): wall
  seconds from the request.

Not part of the test suite; prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from circuitsim.bench.knobs import BenchSetup  # noqa: E402
from circuitsim.bench.session import BenchSession  # noqa: E402
from circuitsim.compare.signals import nrmsd_percent  # noqa: E402
from circuitsim.mechanics import load_model  # noqa: E402
from circuitsim.mechanics.solve import solve  # noqa: E402
from circuitsim.synthesis.options import SynthesisOptions  # noqa: E402


def sustained(seconds: float, chunk: float) -> dict:
    """Model s per wall s of an unthrottled session, and its NRMSD against the ODE."""
    model = load_model(None)
    system = model.system(None, {"V": 57.0, "a": 0.0}, {"flange": False})
    session = BenchSession(
        BenchSetup.from_system(model, system, SynthesisOptions(series="exact")), chunk=chunk
    )
    session.set_state({"y": 0.005})
    started = time.perf_counter()
    while session.t < seconds - 1e-9:
        session.step()
    elapsed = time.perf_counter() - started
    data = session.trace()
    t = np.array(data["t"])
    reference = solve(system, (0.0, seconds), x0=np.array([0.005, 0, 0, 0])).sol(t)
    errors = {
        name: nrmsd_percent(reference[i], np.array(data["states"][name]))
        for i, name in enumerate(session.states)
    }
    return {"chunk_s": chunk, "rate": session.t / elapsed, "nrmsd_percent": errors}


def _call(url: str, data=None) -> dict:
    body = None if data is None else json.dumps(data).encode()
    headers = {"Content-Type": "application/json"}  # the bench refuses a change without it
    request = urllib.request.Request(url, data=body, headers=headers)
    with urllib.request.urlopen(request, timeout=60) as answer:
        return json.loads(answer.read())


def lags(changes: int, chunk: float) -> list[float]:
    """Wall seconds from POST /api/knobs to the first chunk computed with the new speed."""
    process = subprocess.Popen(
        [sys.executable, "-m", "circuitsim", "bench", "--no-browser", "--port", "0",
         "--rate", "1", "--chunk", str(chunk), "--speed", "57", "--amplitude", "0",
         "--no-flange", "--y0", "0.005"],
        cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    try:
        url = None
        while url is None:
            line = process.stdout.readline()
            if not line:
                raise RuntimeError("circuitsim bench exited")
            found = re.search(r" at (http://\S+/) ", line)
            url = found.group(1) if found else None
        time.sleep(2.0)
        out = []
        for k in range(changes):
            sent = time.perf_counter()
            applied = _call(url + "api/knobs", {"speed": 54.0 if k % 2 == 0 else 57.0})
            while _call(url + "api/state")["t"] < applied["t_applied"] + chunk - 1e-9:
                time.sleep(0.01)
            out.append(time.perf_counter() - sent)
            time.sleep(1.0)
        return out
    finally:
        process.terminate()
        process.wait(30)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="model seconds (rate)")
    parser.add_argument("--changes", type=int, default=10, help="knob changes (lag)")
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for chunk in (0.05, 0.1):
        result = sustained(args.seconds, chunk)
        worst = max(result["nrmsd_percent"].values())
        print(f"chunk {chunk:g} s: sustained {result['rate']:.2f} model s per wall s over "
              f"{args.seconds:g} s; circuit vs ODE worst NRMSD {worst:.3f} %")  # fmt: skip
    for chunk in (0.05, 0.1):
        values = lags(args.changes, chunk)
        print(f"chunk {chunk:g} s, rate 1: knob-to-effect lag median "
              f"{statistics.median(values):.3f} s, max {max(values):.3f} s "
              f"({len(values)} changes)")  # fmt: skip
    print(f"load average at end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
