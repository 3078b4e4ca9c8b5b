"""Which requests the bench answers: the host names it serves and same-origin changes.

A server on 127.0.0.1 is still reachable from any web page the user's browser shows: a page
on another site may send requests to it (cross-site request forgery), and a name of that
site's that resolves to 127.0.0.1 (DNS rebinding) makes the browser treat the bench's answers
as that site's own, readable by its scripts. Two rules close both:

- **Host.** Only requests whose ``Host`` header names the bench are answered: 127.0.0.1,
  localhost, [::1] and the ``--host`` given (bound to every interface, ``0.0.0.0`` or
  ``::``: also this machine's host name and any IP address literal, which no rebinding can
  produce). Any other name gets 403, for the page, the API and the websocket alike.
- **Origin.** A request that changes something (any method but GET, HEAD and OPTIONS) and
  the page's websocket must come from the bench's own page: an ``Origin`` header, when
  there is one, must be ``http://`` followed by the request's ``Host``. Scripts (curl,
  urllib) send none and are answered; browsers always send one with such requests.

The API's changes also need ``Content-Type: application/json`` (:mod:`circuitsim.bench.api`),
which no cross-site form or "simple" request can send without the browser first asking the
bench's permission, which it never gives.
"""

from __future__ import annotations

import ipaddress
import socket
from dataclasses import dataclass
from urllib.parse import urlsplit

#: Names of this machine's loopback interface the bench always answers to.
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")

#: Addresses that bind every interface.
ANY_ADDRESS = ("0.0.0.0", "::", "")

#: Methods that change nothing (no Origin rule for them).
SAFE_METHODS = ("GET", "HEAD", "OPTIONS")


def url_host(address: str) -> str:
    """``address`` as it appears in a URL's host part: lower case, IPv6 in brackets."""
    address = address.strip().lower()
    if ":" in address and not address.startswith("["):
        return f"[{address}]"
    return address


def split_host(host: str) -> str:
    """The name of a ``Host`` header or an origin's netloc, without the port (lower case):
    ``localhost:5006`` -> ``localhost``, ``[::1]:5006`` -> ``[::1]``."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[: host.find("]") + 1] if "]" in host else host
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


def _is_ip_literal(name: str) -> bool:
    try:
        ipaddress.ip_address(name.strip("[]"))
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class OriginRules:
    """The host names a bench on ``host`` answers to, and its same-origin rule.

    Parameters
    ----------
    names : frozenset of str
        Host names answered (lower case, IPv6 literals in brackets).
    any_ip : bool
        Any IP address literal is answered too (a bench bound to every interface).
    """

    names: frozenset[str]
    any_ip: bool = False

    @classmethod
    def for_host(cls, host: str) -> OriginRules:
        """The rules of a bench bound to ``host`` (``--host``)."""
        names = set(LOOPBACK_NAMES)
        any_ip = host.strip() in ANY_ADDRESS
        if any_ip:
            names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
        else:
            names.add(url_host(host))
        return cls(frozenset(names), any_ip)

    def serves(self, host: str) -> bool:
        """Whether a ``Host`` header (``name[:port]``) names this bench."""
        name = split_host(host)
        return name in self.names or (self.any_ip and _is_ip_literal(name))

    def websocket_origins(self, port: int) -> list[str]:
        """Bokeh's ``allow_websocket_origin`` list: each name served, at ``port`` (bound to
        every interface, ``*:port`` as well: the IP literals cannot be listed, and
        :meth:`refusal` holds the websocket to its own page's origin)."""
        origins = sorted(f"{name}:{port}" for name in self.names)
        return [*origins, f"*:{port}"] if self.any_ip else origins

    def refusal(self, method: str, host: str, origin: str | None, websocket: bool) -> str | None:
        """Why a request is refused (403), or None when it is answered.

        Parameters
        ----------
        method : str
            The HTTP method.
        host : str
            Its ``Host`` header (tornado puts ``127.0.0.1`` where there is none).
        origin : str or None
            Its ``Origin`` header, if any.
        websocket : bool
            A websocket upgrade (the page's connection).
        """
        if not self.serves(host):
            served = ", ".join(sorted(self.names)) + (" or an IP address" if self.any_ip else "")
            return (
                f"the bench answers requests for {served}, not for host {host!r} (the "
                "Host header): a page of another site must not read or drive it"
            )
        if origin is None or (method.upper() in SAFE_METHODS and not websocket):
            return None
        if not _same_origin(origin, host):
            return (
                f"a request from the page at origin {origin!r} may not change the bench at "
                f"{host!r}: only its own page (origin http://{host}) or a script without an "
                "Origin header may"
            )
        return None


def _same_origin(origin: str, host: str) -> bool:
    """Whether ``origin`` is ``http://`` + ``host`` (the bench serves plain HTTP)."""
    try:
        parts = urlsplit(origin.strip())
    except ValueError:
        return False
    return (
        parts.scheme.lower() == "http"
        and parts.netloc.lower() == host.strip().lower()
        and parts.path in ("", "/")
    )
