"""The bench's web server: Bokeh's tornado server with the page at ``/`` and the JSON API
(:mod:`circuitsim.bench.api`) beside it, on one port.

Bokeh is the ``bench`` extra (``pip install circuitsim[bench]``); it is imported only here
and in :mod:`circuitsim.bench.page`, so the rest of the bench (sessions, the API's logic)
runs without it.
"""

from __future__ import annotations

from circuitsim.bench.api import api_routes
from circuitsim.bench.errors import BenchError
from circuitsim.bench.page import page_application
from circuitsim.bench.runner import BenchRunner


def require_bokeh() -> None:
    """Raise a BenchError saying how to install Bokeh when it is missing."""
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise BenchError(
            "the bench's page needs Bokeh: pip install 'circuitsim[bench]' (or pip install bokeh)"
        ) from None


def bench_server(runner: BenchRunner, host: str = "127.0.0.1", port: int = 5006):
    """A started (not yet looping) Bokeh Server with the page and the API.

    Parameters
    ----------
    runner : BenchRunner
        The running session the page and the API drive.
    host : str
        Address to bind (default: this machine only).
    port : int
        TCP port (0: any free one; ``server.port`` says which).

    Returns
    -------
    bokeh.server.server.Server
        Call ``server.io_loop.start()`` to serve (``server.stop()`` and
        ``server.io_loop.stop()`` end it).

    Raises
    ------
    BenchError
        Bokeh is missing.
    OSError
        The port cannot be bound.
    """
    require_bokeh()
    from bokeh.server.server import Server

    if port == 0:
        port = _free_port(host)

    server = Server(
        {"/": page_application(runner)},
        address=host,
        port=port,
        allow_websocket_origin=["*"]
        if host in ("0.0.0.0", "::")
        else [f"{host}:{port}", f"localhost:{port}", f"127.0.0.1:{port}"],
        extra_patterns=api_routes(runner),
    )
    server.start()
    return server


def _free_port(host: str) -> int:
    """A TCP port free on ``host`` now (the OS's choice for port 0)."""
    import socket

    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return probe.getsockname()[1]
