"""The bench's web server: Bokeh's tornado application with the page at ``/`` and the JSON
API (:mod:`circuitsim.bench.api`) beside it, on one port, behind the origin rules
(:mod:`circuitsim.bench.origins`): a request for a host name the bench does not serve, or a
change (or the page's websocket) from another site's page, is answered 403 before it reaches
the page or the API.

Bokeh is the ``bench`` extra (``pip install circuitsim[bench]``); it is imported only here
and in :mod:`circuitsim.bench.page`, so the rest of the bench (sessions, the API's logic)
runs without it.
"""

from __future__ import annotations

import json

from circuitsim.bench.api import api_routes
from circuitsim.bench.errors import BenchError
from circuitsim.bench.origins import OriginRules, url_host
from circuitsim.bench.page import page_application
from circuitsim.bench.runner import BenchRunner

#: Largest request body tornado reads at all (bytes); past it the connection is closed. The
#: API refuses bodies past :data:`~circuitsim.bench.api.MAX_BODY_BYTES` (64 KiB) with 413
#: first.
MAX_HTTP_BODY = 1 << 20


def require_bokeh() -> None:
    """Raise a BenchError saying how to install Bokeh when it is missing."""
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise BenchError(
            "the bench's page needs Bokeh: pip install 'circuitsim[bench]' (or pip install bokeh)"
        ) from None


def bench_server(runner: BenchRunner, host: str = "127.0.0.1", port: int = 5006):
    """A started (not yet looping) Bokeh server with the page and the API.

    Parameters
    ----------
    runner : BenchRunner
        The running session the page and the API drive.
    host : str
        Address to bind (default: this machine only); its name is one the bench answers
        to (:class:`~circuitsim.bench.origins.OriginRules`).
    port : int
        TCP port (0: any free one; ``server.port`` says which).

    Returns
    -------
    bokeh.server.server.BaseServer
        With ``port``; call ``server.io_loop.start()`` to serve (``server.stop()`` and
        ``server.io_loop.stop()`` end it).

    Raises
    ------
    BenchError
        Bokeh is missing.
    OSError
        The port cannot be bound.
    """
    require_bokeh()
    from bokeh.server.server import BaseServer
    from bokeh.server.tornado import BokehTornado
    from bokeh.server.util import bind_sockets
    from tornado.httpserver import HTTPServer
    from tornado.ioloop import IOLoop

    rules = OriginRules.for_host(host)
    sockets, port = bind_sockets(host, port)
    try:
        application = BokehTornado(
            {"/": page_application(runner)},
            absolute_url=f"http://{url_host(host) or 'localhost'}:{port}",
            extra_websocket_origins=rules.websocket_origins(port),
            extra_patterns=api_routes(runner),
        )
        http = HTTPServer(guarded(application, rules), max_body_size=MAX_HTTP_BODY)
        http.add_sockets(sockets)
    except Exception:
        for s in sockets:
            s.close()
        raise
    server = BaseServer(IOLoop.current(), application, http)
    server.start()
    return server


def guarded(application, rules: OriginRules):
    """A tornado router that answers 403 (``{"error": message}``) to the requests ``rules``
    refuse and hands every other one to ``application``."""
    from tornado.routing import AnyMatches, Matcher, Rule, RuleRouter
    from tornado.web import Application, RequestHandler

    def refusal(request) -> str | None:
        websocket = request.headers.get("Upgrade", "").lower() == "websocket"
        origin = request.headers.get("Origin")
        return rules.refusal(request.method, request.host, origin, websocket)

    class Refused(Matcher):
        def match(self, request):
            return {} if refusal(request) is not None else None

    class Forbidden(RequestHandler):
        def prepare(self) -> None:
            self.set_status(403)
            self.set_header("Content-Type", "application/json")
            self.finish(json.dumps({"error": refusal(self.request)}))

        def check_xsrf_cookie(self) -> None:  # refused in prepare already
            return None

    forbidden = Application([(r".*", Forbidden)])
    return RuleRouter([Rule(Refused(), forbidden), Rule(AnyMatches(), application)])
