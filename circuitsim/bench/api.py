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

A bad value is answered with HTTP 400 and ``{"error": message}``; the session is unchanged.
"""

from __future__ import annotations

import json
import math

from tornado.web import RequestHandler

from circuitsim.bench.errors import BenchError
from circuitsim.bench.runner import BenchRunner, check_rate, check_until


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
        """The request's JSON body.

        Raises
        ------
        BenchError
            Not JSON.
        """
        try:
            return json.loads(self.request.body or b"null")
        except (ValueError, UnicodeDecodeError) as exc:
            raise BenchError(f"the request body is not JSON: {exc}") from None

    def write_error(self, status_code: int, **kwargs) -> None:
        exc = kwargs.get("exc_info", (None, None))[1]
        message = str(exc) if isinstance(exc, BenchError) else self._reason
        self.send({"error": message}, status_code)

    def _handle_request_exception(self, e: BaseException) -> None:
        if isinstance(e, BenchError):
            self.send({"error": str(e)}, 400)
            return
        super()._handle_request_exception(e)


class StateHandler(_Handler):
    def get(self) -> None:
        self.send(state_of(self.runner))


class KnobsHandler(_Handler):
    def post(self) -> None:
        self.send({"t_applied": self.runner.session.set_knobs(self.body())})


class SetStateHandler(_Handler):
    def post(self) -> None:
        self.send({"t_applied": self.runner.session.set_state(self.body())})


class RunHandler(_Handler):
    def post(self) -> None:
        data = self.body()
        if not isinstance(data, dict) or not set(data) <= {"running", "rate", "until"} or not data:
            raise BenchError(
                'expected {"running": true|false}, {"rate": number} and/or {"until": number}'
            )
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
        self.send(state_of(self.runner))


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
