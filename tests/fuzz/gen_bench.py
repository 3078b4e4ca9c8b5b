"""The live bench's HTTP API, one hostile request a case (tests/bench/test_api_fuzz.py's
generator: hostile numbers, nesting, bodies past the limit, foreign Host and Origin headers,
other content types, every method on every path) against one ``circuitsim bench`` started on
127.0.0.1 for the campaign and stopped when it ends.

A case is ``clean`` when the answer is one of the statuses the bench may give and the one its
rules decide (a 400 naming a key of the body); anything else - a 500, a wrong status, a
refusal without a message - is raised as an AssertionError, which the harness counts as a
``traceback``.
"""

from __future__ import annotations

import atexit
import random
import urllib.parse
from collections.abc import Iterator
from functools import cache

from tests.fuzz.harness import Case


@cache
def bench_url() -> str:
    """The address of the campaign's bench (started at the first case, stopped at exit)."""
    from tests.bench.live import BenchProcess

    server = BenchProcess(
        "--speed", "57", "--amplitude", "0", "--no-flange", "--y0", "0.005", "--rate", "inf",
        "--paused",
    )  # fmt: skip
    atexit.register(server.stop)
    return server.url


def _send(seed: int, k: int):
    def call() -> int:
        from tests.bench.live import request
        from tests.bench.test_api_fuzz import ALLOWED, names_some_key, one_request

        base = bench_url()
        r = one_request(random.Random(f"{seed}-{k}"), urllib.parse.urlsplit(base).port)
        status, answer = request(base + r["path"], r["data"], r["method"], r["headers"])
        said = f"{r['method']} /{r['path']} -> {status}: {str(answer)[:200]}"
        expected = r["expected"]
        if status not in ALLOWED:
            raise AssertionError(f"status not allowed: {said}")
        if expected is not None and status != expected:
            raise AssertionError(f"expected {expected}: {said}")
        if expected is None and status not in (200, 400):
            raise AssertionError(f"expected 200 or 400: {said}")
        if status in (400, 403, 413, 415):
            message = answer.get("error") if isinstance(answer, dict) else None
            if not message or (status == 400 and not names_some_key(message, r["keys"])):
                raise AssertionError(f"refusal without a message naming a key: {said}")
        return status

    return call


def cases(seed: int, count: int) -> Iterator[Case]:
    """``count`` requests of ``seed``; the bench starts before the first (outside any case's
    time bound: its first start may compile the engine's kernels)."""
    bench_url()
    for k in range(count):
        yield Case("bench-api", f"seed{seed}-{k}", "", _send(seed, k))
