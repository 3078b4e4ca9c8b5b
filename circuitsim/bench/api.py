"""The bench's HTTP JSON API: tornado request handlers beside the Bokeh page.

=====================  ============================================================
``GET /api/state``     ``{"t", "knobs", "running", "rate", "error", "nrmsd", ...}``
``POST /api/knobs``    knob values, e.g. ``{"speed": 57, "flange": false}`` ->
                       ``{"t_applied": t}``
``POST /api/set_state``  states in SI units, e.g. ``{"y": 0.005}`` -> ``{"t_applied": t}``
``POST /api/run``      ``{"running": bool, "rate": r, "until": T}`` (any of them) -> the
                       state; ``until``: hold the clock at the first chunk boundary at or
                       past model time T (null: run on)
``GET /api/trace``     ``?since=T[&last=S]`` -> ``{"t": [...], "states": {...}, "ode": {...}}``
``GET /api/history``   the knob and state changes with their model and wall times
``GET /api/export/trace.csv``, ``GET /api/export/history.json``: the session's files
=====================  ============================================================

A bad value is answered with HTTP 400 and ``{"error": message}`` naming the key; the session
is unchanged. A change (POST) needs ``Content-Type: application/json`` (else 415) and a body
of at most :data:`MAX_BODY_BYTES` (else 413) nesting at most :data:`MAX_DEPTH` arrays or
objects; a number must be one a float holds (a 400-digit integer is refused, not rounded to
infinity). The origin rules (403) are the server's (:mod:`circuitsim.bench.origins`).
"""

from __future__ import annotations

import json
import math
import re
import sys

from tornado.web import RequestHandler, stream_request_body

from circuitsim.bench.errors import BenchError
from circuitsim.bench.runner import BenchRunner, check_rate, check_until

#: Largest request body (bytes) a change is read from: a knob request is tens of bytes.
MAX_BODY_BYTES = 64 * 1024

#: Deepest nesting of arrays and objects in a request body (every valid body nests 1).
MAX_DEPTH = 32

#: The keys of ``POST /api/run``.
RUN_KEYS = ("running", "rate", "until")


def _finite(value):
    """JSON has no NaN or infinity: None in their place (recursively)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def state_of(runner: BenchRunner) -> dict:
    """The answer of ``GET /api/state``."""
    session = runner.session
    with session.lock:
        current = dict(zip(session.states, map(float, session.circuit_state), strict=True))
        return _finite(
            {
                "t": session.t,
                "knobs": session.knob_values(),
                "running": runner.running,
                "rate": runner.rate,
                "until": runner.until,
                "error": runner.error,
                "nrmsd_percent": session.nrmsd(),
                "resistors": session.resistors,
                "pots": session.pot_settings(),
                "state": current,
                "chunk": session.chunk,
                "knob_info": [
                    {
                        "name": k.name,
                        "kind": k.kind,
                        "parameter": k.parameter,
                        "unit": k.unit,
                        "description": k.description,
                        "parts": list(k.parts),
                    }
                    for k in session.knobs
                ],
                "states": list(session.states),
                "units": list(session.units),
            }
        )


class _Handler(RequestHandler):
    """Shared by the handlers: the runner, JSON in and out, 400 for a BenchError."""

    def initialize(self, runner: BenchRunner) -> None:
        self.runner = runner

    def check_xsrf_cookie(self) -> None:  # a local JSON API for scripts: no cookies to check
        return None

    def send(self, data, status: int = 200) -> None:
        self.set_status(status)
        self.set_header("Content-Type", "application/json")
        self.finish(json.dumps(_finite(data), allow_nan=False))

    def body(self):
        """The request's JSON body (see :func:`parse_body`).

        Raises
        ------
        BenchError
            Not JSON, too deep, a number no float holds.
        """
        return parse_body(self.request.body)

    def write_error(self, status_code: int, **kwargs) -> None:
        exc = kwargs.get("exc_info", (None, None))[1]
        message = str(exc) if isinstance(exc, BenchError) else self._reason
        self.send({"error": message}, status_code)

    def _handle_request_exception(self, e: BaseException) -> None:
        if isinstance(e, BenchError):
            self.send({"error": str(e)}, 400)
            return
        super()._handle_request_exception(e)


@stream_request_body
class _ChangeHandler(_Handler):
    """A change (POST): JSON only (415 otherwise), the body read up to MAX_BODY_BYTES (413
    past it, whether announced by Content-Length or not)."""

    def prepare(self) -> None:
        self._chunks: list[bytes] = []
        self._size = 0
        if self.request.method != "POST":  # answered 405 by tornado
            return
        kind = self.request.headers.get("Content-Type", "")
        if kind.split(";")[0].strip().lower() != "application/json":
            self.send(
                {
                    "error": f"a change needs Content-Type: application/json, got "
                    f"{kind or 'none'!r} (curl: -H 'Content-Type: application/json')"
                },
                415,
            )
            return
        length = self.request.headers.get("Content-Length", "0")
        if not length.isdigit() or int(length) > MAX_BODY_BYTES:
            self._too_large(length)

    def data_received(self, chunk: bytes) -> None:
        self._size += len(chunk)
        if self._size <= MAX_BODY_BYTES:
            self._chunks.append(chunk)

    def body(self):
        if self._size > MAX_BODY_BYTES:
            self._too_large(str(self._size))
            return None
        return parse_body(b"".join(self._chunks))

    def _too_large(self, length: str) -> None:
        self.send(
            {
                "error": f"the request body ({length} bytes) is past the bench's limit of "
                f"{MAX_BODY_BYTES} bytes"
            },
            413,
        )

    def change(self, data) -> dict:
        """The answer to a body ``data``."""
        raise NotImplementedError

    def post(self) -> None:
        data = self.body()
        if not self._finished:
            self.send(self.change(data))


class StateHandler(_Handler):
    def get(self) -> None:
        self.send(state_of(self.runner))


class KnobsHandler(_ChangeHandler):
    def change(self, data) -> dict:
        try:
            return {"t_applied": self.runner.session.set_knobs(data)}
        except BenchError as exc:
            raise _naming_keys(exc, data) from None


class SetStateHandler(_ChangeHandler):
    def change(self, data) -> dict:
        try:
            return {"t_applied": self.runner.session.set_state(data)}
        except BenchError as exc:
            raise _naming_keys(exc, data) from None


class RunHandler(_ChangeHandler):
    def change(self, data) -> dict:
        try:
            return self._run(data)
        except BenchError as exc:
            raise _naming_keys(exc, data) from None

    def _run(self, data) -> dict:
        if not isinstance(data, dict) or not data:
            raise BenchError(
                'expected {"running": true|false}, {"rate": number} and/or {"until": number}'
            )
        unknown = [key for key in data if key not in RUN_KEYS]
        if unknown:
            raise BenchError(f"unknown key {unknown[0]!r} of /api/run; the keys are "
                             f"{', '.join(RUN_KEYS)}")  # fmt: skip
        if "running" in data and not isinstance(data["running"], bool):
            raise BenchError(f"running must be true or false, got {data['running']!r}")
        check_rate(data.get("rate", 1.0))  # every value checked before any is applied
        check_until(data.get("until"))
        if "rate" in data:
            self.runner.set_rate(data["rate"])
        if "until" in data:  # before resuming: the clock must not run past it
            self.runner.set_until(data["until"])
        if "running" in data:
            self.runner.resume() if data["running"] else self.runner.pause()
        return state_of(self.runner)


class TraceHandler(_Handler):
    def get(self) -> None:
        since = _number_argument(self, "since", -math.inf)
        last = _number_argument(self, "last", None)
        self.send(self.runner.session.trace(since, last))


class HistoryHandler(_Handler):
    def get(self) -> None:
        self.set_header("Content-Type", "application/json")
        self.finish(self.runner.session.history_json())


class ExportHandler(_Handler):
    def get(self, name: str) -> None:
        session = self.runner.session
        if name == "trace.csv":
            text, kind = session.trace_csv(), "text/csv"
        else:
            text, kind = session.history_json(), "application/json"
        self.set_header("Content-Type", kind)
        self.set_header("Content-Disposition", f'attachment; filename="bench_{name}"')
        self.finish(text)


def parse_body(body: bytes):
    """A change's body as JSON: at most :data:`MAX_DEPTH` deep, every number of an object's
    values one a float holds (``NaN`` and ``Infinity`` pass: the checks of each key say
    where they are refused).

    Raises
    ------
    BenchError
        Not UTF-8 JSON, nested too deep, an integer past the float range (naming its key).
    """
    try:
        text = body.decode("utf-8") if body else "null"
    except UnicodeDecodeError as exc:
        raise BenchError(f"the request body is not JSON (not UTF-8: {exc})") from None
    depth, key = nesting_depth(text)
    if depth > MAX_DEPTH:
        where = f"{key!r}: " if key is not None else ""
        raise BenchError(
            f"{where}the request body nests arrays or objects {depth} deep; the bench reads at "
            f"most {MAX_DEPTH} (a change is one object of keys and values)"
        )
    try:
        data = json.loads(text, parse_int=_read_integer)
    except ValueError as exc:
        raise BenchError(f"the request body is not JSON: {exc}") from None
    if isinstance(data, dict):
        for key, value in data.items():
            _check_float_range(key, value)
    return data


def nesting_depth(text: str) -> tuple[int, str | None]:
    """The deepest nesting of ``[`` and ``{`` in JSON text (outside its strings), and the key
    of the outer object under which it is (None: not under a key)."""
    depth = deepest = 0
    key = deepest_key = last_string = None
    for token in _TOKENS.finditer(text):
        char = token.group()
        if char in "[{":
            depth += 1
            if depth > deepest:
                deepest, deepest_key = depth, key
        elif char in "]}":
            depth -= 1
        elif char == ":" and depth == 1 and last_string is not None:
            key = last_string
        elif char.startswith('"'):
            last_string = char
            continue
        last_string = None
    if deepest_key is not None:
        try:
            deepest_key = json.loads(deepest_key)
        except ValueError:
            deepest_key = deepest_key[1:-1]
    return deepest, deepest_key


#: JSON strings, brackets and colons (what the depth and the keys are read from).
_TOKENS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}:]', re.DOTALL)


class _LongInteger:
    """An integer of more digits than any float holds (read without converting it)."""

    def __init__(self, digits: int):
        self.digits = digits

    def __repr__(self) -> str:
        return f"an integer of {self.digits} digits"


#: Digits of the largest integer a float holds (1.8e308).
_FLOAT_DIGITS = len(str(int(sys.float_info.max)))


def _read_integer(text: str):
    digits = len(text.lstrip("-"))
    return int(text) if digits <= _FLOAT_DIGITS else _LongInteger(digits)


def _check_float_range(key: str, value) -> None:
    """Refuse an integer (or one in a list) no float holds, naming ``key``."""
    for item in value if isinstance(value, list) else [value]:
        if isinstance(item, int) and not isinstance(item, bool):
            try:
                float(item)
            except OverflowError:
                item = _LongInteger(len(str(abs(item))))
        if isinstance(item, _LongInteger):
            raise BenchError(
                f"{key!r}: {item!r} is past the largest number the bench computes with "
                f"({sys.float_info.max:.4g})"
            )


def _naming_keys(exc: BenchError, data) -> BenchError:
    """``exc`` with the body's keys in front of its message when it names none of them (the
    translator's "these values change the circuit's wiring" names parts, not knobs)."""
    message = str(exc)
    if not isinstance(data, dict) or not data or any(names_key(message, k) for k in data):
        return exc
    return BenchError(f"{', '.join(map(repr, data))}: {message}")


def names_key(message: str, key: str) -> bool:
    """Whether ``message`` names ``key`` (as a word of its own, quoted or not)."""
    return re.search(rf"(?<!\w){re.escape(key)}(?!\w)", message) is not None


def _number_argument(handler: RequestHandler, name: str, default):
    """A query argument as a number (``since=1.5``).

    Raises
    ------
    BenchError
        Not a number.
    """
    text = handler.get_query_argument(name, None)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        raise BenchError(f"{name} must be a number of model seconds, got {text!r}") from None
    if math.isnan(value):
        raise BenchError(f"{name} must be a number of model seconds, got {text!r}")
    return value


def api_routes(runner: BenchRunner) -> list[tuple]:
    """The API's URL patterns for tornado (Bokeh's ``extra_patterns``)."""
    extra = {"runner": runner}
    return [
        (r"/api/state", StateHandler, extra),
        (r"/api/knobs", KnobsHandler, extra),
        (r"/api/set_state", SetStateHandler, extra),
        (r"/api/run", RunHandler, extra),
        (r"/api/trace", TraceHandler, extra),
        (r"/api/history", HistoryHandler, extra),
        (r"/api/export/(trace\.csv|history\.json)", ExportHandler, extra),
    ]
