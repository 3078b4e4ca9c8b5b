"""The live bench server the API and browser tests share."""

import pytest

from tests.bench.live import BenchProcess


@pytest.fixture(scope="module")
def bench_57():
    """The wheelset at 57 m/s, flange off, no forcing, from a 5 mm push, unthrottled."""
    server = BenchProcess(
        "--speed", "57", "--amplitude", "0", "--no-flange", "--y0", "0.005", "--rate", "inf"
    )
    yield server.url
    server.stop()
