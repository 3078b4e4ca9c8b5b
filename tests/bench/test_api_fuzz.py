"""A bounded, seeded fuzz of the bench's HTTP API on a running ``circuitsim bench``: 400
requests from a seeded generator (hostile numbers as JSON text: 4000-digit integers, 1e308,
NaN, Infinity, denormals; strings, nesting to 2000 deep, unknown keys, bodies past the size
limit, bytes that are no UTF-8; foreign Host and Origin headers, other content types, every
method on every path). Each answer is one of 200, 400, 403, 404, 405, 413, 415, never a 500;
the header and routing rules decide the status exactly where they apply, and every 400 names
the key it refuses when the body is an object with keys.

The generator never sends ``"running": true``: the clock stays held at t = 0, so the fuzz
costs a bounded number of requests and no chunks (running is tested in test_api.py)."""

import json
import random
import urllib.parse
from collections import Counter

import pytest

from circuitsim.bench.api import MAX_BODY_BYTES, names_key
from tests.bench.live import request

SEED = 43
REQUESTS = 400

#: The only statuses the bench may answer.
ALLOWED = {200, 400, 403, 404, 405, 413, 415}

KNOBS = ["speed", "freq", "amplitude", "flange", "m", "I", "k"]
STATES = ["y", "psi", "y_dot", "psi_dot"]
RUN = ["running", "rate", "until"]
ODD_KEYS = ["", "x", "__proto__", "speed ", "Speed", "ψ", 'a"b', "0", "constructor"]

CHANGES = {"api/knobs": KNOBS, "api/set_state": STATES, "api/run": RUN}
READS = ["api/state", "api/history", "api/export/trace.csv", "api/export/history.json"]
MISSING = ["api/nope", "api/export/other.csv", "api/knobs/x", "api", "favicon.ico.x"]

NUMBERS = [
    "0", "-0", "-0.0", "1", "-1", "57", "54", "56.5", "1e308", "-1e308", "1.7976931348623157e308",
    "1e309", "-1e400", "5e-324", "1e-300", "2.5e-7", "9007199254740993", "NaN", "Infinity",
    "-Infinity", "9" * 309, "-" + "9" * 400, "9" * 4000, "1" * 4301, "0.005", "0.2", "12",
    "1e3", "250", "250.0001", "-57",
]  # fmt: skip


def number(rng: random.Random) -> str:
    """A number as JSON text (Python's JSON reads NaN and Infinity too)."""
    if rng.random() < 0.6:
        return rng.choice(NUMBERS)
    return f"{rng.uniform(-10, 10):.6g}e{rng.randint(-330, 330)}"  # past 1e308: inf


def value(rng: random.Random, depth: int = 0) -> str:
    """Any JSON value as text, hostile numbers most often."""
    kind = rng.random()
    if kind < 0.55 or depth > 3:
        return number(rng)
    if kind < 0.65:
        return rng.choice(["true", "false", "null"])
    if kind < 0.75:
        return json.dumps(rng.choice(["fast", "", "1", "NaN", "\u0000", "ψ" * 50, "x" * 1000]))
    if kind < 0.85:
        return "[" + ", ".join(value(rng, depth + 1) for _ in range(rng.randint(0, 3))) + "]"
    if kind < 0.93:
        n = rng.choice([2, 31, 33, 200, 2000])
        return "[" * n + "]" * n
    return "{" + f'"{rng.choice(KNOBS)}": {value(rng, depth + 1)}' + "}"


def body(rng: random.Random, keys: list[str]) -> tuple[bytes, list[str] | None]:
    """A request body and, when it is a JSON object, its keys."""
    kind = rng.random()
    if kind < 0.8:
        names = [rng.choice(keys) if rng.random() < 0.85 else rng.choice(ODD_KEYS)
                 for _ in range(rng.choice([1, 1, 1, 2, 3]))]  # fmt: skip
        pairs = []
        for name in names:
            text = value(rng)
            if name == "running" and text == "true":
                text = "false"  # the clock stays held (see the module's description)
            pairs.append(f"{json.dumps(name)}: {text}")
        return ("{" + ", ".join(pairs) + "}").encode(), names
    return rng.choice([
        b"", b"null", b"[]", b"{}", b"{not json", b'{"speed": 5', b"\xff\xfe{}", b"NaN",
        b"9" * 5000, b"[" * 100_000, b'{"speed": "' + b"x" * MAX_BODY_BYTES + b'"}',
        json.dumps({rng.choice(keys): 0.001}).encode(),
    ]), None  # fmt: skip


def one_request(rng: random.Random, port: int) -> dict:
    """A request (method, path, headers, body) and the status its headers and route decide
    (None: the body's values decide, 200 or 400)."""
    host_ok, origin_ok = rng.random() < 0.9, rng.random() < 0.9
    host = f"localhost:{port}" if host_ok else rng.choice(["evil.example", "localhost.evil:1"])
    headers = {"Host": host}
    if rng.random() < 0.4:  # a browser: its origin, or another site's
        headers["Origin"] = f"http://{host}" if origin_ok else "http://evil.example"
    else:
        origin_ok = True  # a script sends none
    json_content = rng.random() < 0.9
    headers["Content-Type"] = (
        rng.choice(["application/json", "application/json; charset=utf-8", "Application/JSON"])
        if json_content
        else rng.choice(["text/plain", "application/x-www-form-urlencoded", ""])
    )
    where = rng.random()
    keys, data = None, None
    if where < 0.6:
        path = rng.choice(list(CHANGES))
        method = "POST" if rng.random() < 0.9 else rng.choice(["GET", "PUT", "DELETE", "PATCH"])
        data, keys = body(rng, CHANGES[path])
        route = 405 if method != "POST" else None
    elif where < 0.8:
        since, last = number(rng), number(rng) if rng.random() < 0.5 else None
        query = {"since": since} if rng.random() < 0.8 else {"since": rng.choice(["abc", ""])}
        if last is not None:
            query["last"] = last
        path = "api/trace?" + urllib.parse.urlencode(query)
        method, route = "GET", None
    elif where < 0.9:
        path = rng.choice(READS)
        method = "GET" if rng.random() < 0.8 else rng.choice(["POST", "PUT", "DELETE"])
        data = b"{}" if method != "GET" else None
        route = 200 if method == "GET" else 405
    else:
        path, method, route = rng.choice(MISSING), rng.choice(["GET", "POST"]), 404
        data = b"{}" if method == "POST" else None
    if not host_ok or (method != "GET" and not origin_ok):
        expected = 403
    elif route is not None:
        expected = route
    elif method == "POST" and not json_content:
        expected = 415
    elif method == "POST" and len(data) > MAX_BODY_BYTES:
        expected = 413
    else:
        expected = None
    return {"method": method, "path": path, "headers": headers, "data": data,
            "keys": keys, "expected": expected}  # fmt: skip


def names_some_key(message: str, keys: list[str] | None) -> bool:
    """Whether a 400's message names one of the body's keys (the empty key as ``''``; True
    for a body that is no object)."""
    return not keys or any(names_key(message, key) if key else "''" in message for key in keys)


def run_fuzz(base: str, seed: int = SEED, count: int = REQUESTS) -> tuple[Counter, list[str]]:
    """Send ``count`` requests of ``seed``'s generator to the bench at ``base``: the statuses
    seen, and what went wrong (empty: every answer as it should be)."""
    rng = random.Random(seed)
    port = urllib.parse.urlsplit(base).port
    statuses, wrong = Counter(), []
    for k in range(count):
        r = one_request(rng, port)
        status, answer = request(base + r["path"], r["data"], r["method"], r["headers"])
        statuses[status] += 1
        said = (
            f"request {k}: {r['method']} /{r['path']} {r['headers']} {(r['data'] or b'')[:120]!r}"
        )
        if status not in ALLOWED:
            wrong.append(f"{said} -> {status} {str(answer)[:300]}")
        elif r["expected"] is not None and status != r["expected"]:
            wrong.append(f"{said} -> {status}, expected {r['expected']}: {str(answer)[:300]}")
        elif r["expected"] is None and status not in (200, 400):
            wrong.append(f"{said} -> {status}, expected 200 or 400: {str(answer)[:300]}")
        elif status in (400, 403, 413, 415):
            message = answer.get("error") if isinstance(answer, dict) else None
            if not message:
                wrong.append(f"{said} -> {status} without a message: {str(answer)[:300]}")
            elif status == 400 and not names_some_key(message, r["keys"]):
                wrong.append(f"{said} -> 400 naming none of its keys: {message}")
    return statuses, wrong


@pytest.mark.slow
def test_the_api_fuzz_gets_no_500_and_every_refusal_says_why(bench_57):
    statuses, wrong = run_fuzz(bench_57)
    assert not wrong, f"{len(wrong)} of {REQUESTS} wrong ({dict(statuses)}):\n" + "\n".join(
        wrong[:20]
    )
    assert sum(statuses.values()) == REQUESTS
    assert {200, 400, 403, 404, 405, 413, 415} <= set(statuses)  # each rule was exercised
    # the bench is intact: it answers, its state is finite, its clock held
    status, state = request(bench_57 + "api/state")
    assert status == 200 and state["error"] is None and state["running"] is False
    assert all(v is not None for v in state["state"].values())
    assert all(v is not None for v in state["knobs"].values())
