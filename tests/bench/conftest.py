"""The live bench server the API and browser tests share."""

import pytest

from tests.bench.live import BenchProcess


@pytest.fixture(scope="module")
def bench_57():
    """The wheelset at 57 m/s, flange off, no forcing, from a 5 mm push, unthrottled, held at
    t = 0 until a test runs it (``live.run_until``): at 57 m/s without the flange the hunting
    grows without bound, and the ideal circuit's engine stops at t = 53.7 s (node voltages
    past 1e12 V), so a test must not let it run on unwatched."""
    server = BenchProcess(
        "--speed", "57", "--amplitude", "0", "--no-flange", "--y0", "0.005", "--rate", "inf",
        "--paused",
    )  # fmt: skip
    yield server.url
    server.stop()
