"""The bench answers only its own host names and its own page: a page of another site can
neither drive it (cross-site requests) nor read it (DNS rebinding), while scripts without an
``Origin`` header (curl, urllib) and the page's own origin still work; and hostile values get
400 with a message naming the key, never a 500 (issue 43's requests, on a running
``circuitsim bench``)."""

import asyncio
import json
import urllib.parse

import pytest
from tornado.httpclient import HTTPClientError, HTTPRequest
from tornado.websocket import websocket_connect

from circuitsim.bench.api import MAX_BODY_BYTES, MAX_DEPTH, names_key, nesting_depth, parse_body
from circuitsim.bench.errors import BenchError
from circuitsim.bench.origins import OriginRules, split_host
from tests.bench.live import request

EVIL = {"Host": "evil.example:5917", "Origin": "http://evil.example"}
HUGE = "9" * 4000  # issue 43: "int too large to convert to float"


def port_of(base: str) -> int:
    return urllib.parse.urlsplit(base).port


def speed(base: str) -> float:
    return request(base + "api/state")[1]["knobs"]["speed"]


def test_the_cross_site_request_of_the_issue_is_refused(bench_57):
    # curl -X POST -H 'Host: evil.example:5917' -H 'Origin: http://evil.example'
    #      -H 'Content-Type: text/plain' -d '{"speed": 60}' .../api/knobs
    status, answer = request(
        bench_57 + "api/knobs", b'{"speed": 60}', headers={**EVIL, "Content-Type": "text/plain"}
    )
    assert status == 403
    assert "not for host 'evil.example:5917'" in answer["error"]
    assert speed(bench_57) == 57.0


@pytest.mark.parametrize("path", ["", "api/state", "api/trace?since=0", "api/history",
                                  "api/export/trace.csv", "static/js/bokeh.min.js"])  # fmt: skip
def test_a_foreign_host_reads_nothing(bench_57, path):
    """DNS rebinding: evil.example resolved to 127.0.0.1 sends Host: evil.example."""
    status, answer = request(bench_57 + path, headers={"Host": "evil.example:5917"})
    assert status == 403
    assert "the bench answers requests for 127.0.0.1, [::1], localhost" in answer["error"]


@pytest.mark.parametrize("host", ["evil.example", "localhost.evil.example", "127.0.0.1.nip.io",
                                  "localhost.", "[::2]"])  # fmt: skip
def test_only_the_names_served_are_answered(bench_57, host):
    port = port_of(bench_57)
    status, answer = request(bench_57 + "api/state", headers={"Host": f"{host}:{port}"})
    assert status == 403 and "Host header" in answer["error"]


@pytest.mark.parametrize("name", ["127.0.0.1", "localhost", "LOCALHOST", "[::1]"])
def test_the_loopback_names_are_answered(bench_57, name):
    port = port_of(bench_57)
    status, state = request(bench_57 + "api/state", headers={"Host": f"{name}:{port}"})
    assert status == 200 and state["knobs"]["speed"] == 57.0


@pytest.mark.parametrize(
    "origin", ["http://evil.example", "null", "https://localhost:{port}", "http://localhost:1",
               "http://127.0.0.1:{port}.evil.example", "file://"],
)  # fmt: skip
def test_a_change_from_another_origin_is_refused(bench_57, origin):
    port = port_of(bench_57)
    headers = {"Host": f"localhost:{port}", "Origin": origin.format(port=port)}
    for path, body in [("api/knobs", {"speed": 60}), ("api/set_state", {"y": 0.001}),
                       ("api/run", {"running": True})]:  # fmt: skip
        status, answer = request(bench_57 + path, body, headers=headers)
        assert status == 403
        assert "may not change the bench" in answer["error"]
    _, state = request(bench_57 + "api/state")
    assert state["knobs"]["speed"] == 57.0 and state["running"] is False


@pytest.mark.parametrize("kind", ["text/plain", "application/x-www-form-urlencoded",
                                  "multipart/form-data; boundary=x", ""])  # fmt: skip
def test_a_change_needs_json_content(bench_57, kind):
    """What a cross-site "simple" request (or curl's -d without a header) sends."""
    headers = {"Content-Type": kind}
    status, answer = request(bench_57 + "api/knobs", b'{"speed": 60}', headers=headers)
    assert status == 415
    assert "Content-Type: application/json" in answer["error"]
    assert speed(bench_57) == 57.0


def test_scripts_and_the_pages_own_origin_change_the_knobs(bench_57):
    port = port_of(bench_57)
    assert request(bench_57 + "api/knobs", {"speed": 56})[0] == 200  # no Origin: curl, urllib
    assert speed(bench_57) == 56.0
    for host in (f"localhost:{port}", f"127.0.0.1:{port}", f"[::1]:{port}"):
        headers = {"Host": host, "Origin": f"http://{host}",
                   "Content-Type": "application/json; charset=utf-8"}  # fmt: skip
        status, answer = request(bench_57 + "api/knobs", {"speed": 55}, headers=headers)
        assert status == 200, answer
    assert speed(bench_57) == 55.0
    assert request(bench_57 + "api/knobs", {"speed": 57})[0] == 200
    # reads carry no Origin rule: the browser keeps a cross-site page from reading them
    status, _ = request(bench_57 + "api/state", headers={"Origin": "http://evil.example"})
    assert status == 200


def _websocket(base: str, headers: dict) -> int:
    """HTTP status of a websocket handshake on the page's /ws (101 when it opens)."""

    async def connect() -> int:
        url = base.replace("http://", "ws://") + "ws"
        try:
            connection = await websocket_connect(HTTPRequest(url, headers=headers))
        except HTTPClientError as error:
            return error.code
        connection.close()
        return 101

    loop = asyncio.new_event_loop()  # not asyncio.run: it unsets the thread's loop, which
    try:  # the browser test's DevTools client (cdp.py) gets with get_event_loop
        return loop.run_until_complete(connect())
    finally:
        loop.close()


def test_the_websocket_follows_the_same_rules(bench_57):
    port = port_of(bench_57)
    assert _websocket(bench_57, {"Origin": "http://evil.example"}) == 403
    assert _websocket(bench_57, {"Host": "evil.example", "Origin": "http://evil.example"}) == 403
    assert _websocket(bench_57, {"Host": f"localhost:{port}",
                                 "Origin": f"http://localhost:{port}"}) == 101  # fmt: skip


@pytest.mark.parametrize(
    "path, body, key",
    [
        ("api/knobs", f'{{"speed": {HUGE}}}', "speed"),
        ("api/knobs", f'{{"speed": -{HUGE}}}', "speed"),
        ("api/set_state", f'{{"y": {HUGE}}}', "y"),
        ("api/run", f'{{"rate": {HUGE}}}', "rate"),
        ("api/run", f'{{"until": {HUGE}}}', "until"),
        ("api/run", '{"until": ' + "9" * 400 + "}", "until"),  # 400 digits: 1e399 as a float
        ("api/set_state", '{"y": 1e308}', "y"),
        ("api/set_state", '{"psi": -1e308}', "psi"),
        ("api/set_state", '{"y": 1}', "y"),  # 56 V on the y node: past the 13 V swing
        ("api/set_state", '{"y": Infinity}', "y"),
        ("api/knobs", '{"speed": NaN}', "speed"),
        ("api/knobs", '{"freq": 1e300}', "freq"),
        ("api/knobs", '{"freq": -1}', "freq"),
        ("api/knobs", '{"speed": -57}', "speed"),  # the translator's "wiring" message
        ("api/run", '{"rate": NaN}', "rate"),
        ("api/run", '{"running": true, "bogus": 1}', "bogus"),
    ],
)
def test_hostile_numbers_get_400_naming_the_key(bench_57, path, body, key):
    _, before = request(bench_57 + "api/state")
    status, answer = request(bench_57 + path, body.encode())
    assert status == 400
    assert names_key(answer["error"], key), answer["error"]
    _, after = request(bench_57 + "api/state")
    assert after["knobs"] == before["knobs"] and after["state"] == before["state"]
    assert (after["running"], after["rate"], after["until"]) == (False, before["rate"], None)
    assert all(v is not None for v in after["state"].values())  # no state reads null


def test_deep_nesting_and_large_bodies_are_refused(bench_57):
    status, answer = request(bench_57 + "api/run", b"[" * 100_000)  # issue 43: RecursionError
    assert status == 413 and f"limit of {MAX_BODY_BYTES} bytes" in answer["error"]
    status, answer = request(
        bench_57 + "api/knobs", b'{"speed": ' + b"[" * 1000 + b"]" * 1000 + b"}"
    )
    assert (
        status == 400
        and "'speed': the request body nests arrays or objects 1001 deep" in (answer["error"])
    )
    big = json.dumps({"speed": 57, "pad": "x" * MAX_BODY_BYTES}).encode()
    status, answer = request(bench_57 + "api/knobs", big)
    assert status == 413 and str(len(big)) in answer["error"]
    status, _ = request(bench_57 + "api/knobs", b'{"speed": 57}' + b" " * (MAX_BODY_BYTES - 13))
    assert status == 200  # exactly the limit is read


def test_a_chunked_body_past_the_limit_is_refused(bench_57):
    """No Content-Length to refuse it by: the body is counted as it arrives."""
    import http.client

    port = port_of(bench_57)
    connection = http.client.HTTPConnection("127.0.0.1", port, timeout=60)
    chunks = (b'{"speed": 57, "pad": "' + b"x" * 8192 for _ in range(10))
    connection.request("POST", "/api/knobs", body=chunks, encode_chunked=True,
                       headers={"Content-Type": "application/json"})  # fmt: skip
    answer = connection.getresponse()
    assert answer.status == 413 and b"past the bench's limit" in answer.read()
    connection.close()


# --- the rules and the parser alone ----------------------------------------------------------


def test_the_rules_of_a_bench_bound_to_every_interface():
    rules = OriginRules.for_host("0.0.0.0")
    assert rules.serves("192.168.1.20:5006") and rules.serves("[fe80::1]:5006")
    assert rules.serves("localhost:5006") and not rules.serves("evil.example:5006")
    assert rules.websocket_origins(5006)[-1] == "*:5006"
    refusal = rules.refusal("POST", "192.168.1.20:5006", "http://evil.example", False)
    assert "may not change the bench" in refusal
    assert rules.refusal("POST", "192.168.1.20:5006", "http://192.168.1.20:5006", False) is None


def test_the_rules_of_a_named_host():
    rules = OriginRules.for_host("Bench.Lan")
    assert rules.serves("bench.lan:5006") and rules.serves("127.0.0.1")
    assert not rules.serves("192.168.1.20:5006")  # an IP literal only when bound to all
    assert rules.websocket_origins(80) == ["127.0.0.1:80", "[::1]:80", "bench.lan:80",
                                           "localhost:80"]  # fmt: skip
    assert OriginRules.for_host("::1").websocket_origins(1) == ["127.0.0.1:1", "[::1]:1",
                                                                "localhost:1"]  # fmt: skip
    assert rules.refusal("GET", "bench.lan:5006", "http://evil.example", False) is None
    assert rules.refusal("GET", "bench.lan:5006", "http://evil.example", True) is not None
    assert [split_host(h) for h in ("[::1]:80", "[::1]", "a:1", "a")] == ["[::1]", "[::1]",
                                                                          "a", "a"]  # fmt: skip


def test_the_parser_counts_depth_outside_strings():
    assert nesting_depth('{"a": "[[[[{{{{\\"[["}') == (1, None)
    assert nesting_depth("[[[]], {}]") == (3, None)
    assert nesting_depth('{"x": 1, "k": [[[2]]], "z": {}}') == (4, "k")
    assert parse_body(b'{"a": [1, 2]}') == {"a": [1, 2]}
    with pytest.raises(BenchError, match=f"at most {MAX_DEPTH}"):
        parse_body(b"[" * (MAX_DEPTH + 1) + b"]" * (MAX_DEPTH + 1))
    parse_body(b"[" * MAX_DEPTH + b"]" * MAX_DEPTH)
    with pytest.raises(BenchError, match="'k': an integer of 5000 digits"):
        parse_body(b'{"k": -' + b"1" * 5000 + b"}")  # past Python's own 4300-digit limit
    with pytest.raises(BenchError, match="not JSON"):
        parse_body(b"\xff")
