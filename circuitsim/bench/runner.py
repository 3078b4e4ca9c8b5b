"""The bench's clock: a thread that steps a session chunk by chunk at ``rate`` model seconds
per wall second (or as fast as it can: ``rate = inf``), with pause and resume.

The session is kept at most one chunk ahead of the clock, so a knob change acts within about
one chunk of model time (plus the time to compute it). A chunk that fails (no convergence)
stops the clock; ``error`` says why and the session keeps the state before the chunk.

``until`` holds the clock at the first chunk boundary at or past a model time: a script (or a
test) that must act at a known model time asks for it, rather than polling a clock that runs
on (unthrottled, the session can run hundreds of chunks between two polls of a loaded
machine).
"""

from __future__ import annotations

import math
import threading
import time

from circuitsim.bench.errors import BenchError
from circuitsim.bench.session import BenchSession
from circuitsim.solver.jit import use_numba


class BenchRunner:
    """Steps ``session`` in a background thread.

    Parameters
    ----------
    session : BenchSession
    rate : float
        Model seconds per wall second (> 0; ``inf``: unthrottled).
    running : bool
        Start running (True) or paused.
    """

    def __init__(self, session: BenchSession, rate: float = 1.0, running: bool = True):
        self.session = session
        self.rate = check_rate(rate)
        self.error: str | None = None
        #: Model time (s) at whose chunk boundary the clock is held (None: runs on).
        self.until: float | None = None
        self._running = running
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._anchor = (time.monotonic(), session.t)  # wall time, model time
        self._thread = threading.Thread(target=self._loop, name="bench-runner", daemon=True)

    @property
    def running(self) -> bool:
        """Whether the clock runs (not paused, stopped or failed)."""
        return self._running and self.error is None and not self._stop.is_set()

    def start(self) -> BenchRunner:
        """Start the thread; returns self."""
        use_numba()  # the start-up library's kernels hold the GIL; numba's release it
        self._thread.start()
        return self

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the thread (waits for the chunk in progress)."""
        self._stop.set()
        self._wake.set()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def pause(self) -> None:
        """Hold the clock after the chunk in progress."""
        self._running = False

    def resume(self) -> None:
        """Run again from the model time reached (the clock does not catch up the pause).

        After a failed chunk (``error``) the chunk is tried again from the state before it,
        with the knobs and state as they are now (e.g. after an overload, a lower speed or a
        push back)."""
        self.error = None
        self._reanchor()
        self._running = True
        self._wake.set()

    def set_until(self, until: float | None) -> None:
        """Hold the clock at the first chunk boundary at or past model time ``until`` (s;
        None: run on). A time already reached holds it after the chunk in progress.

        Raises
        ------
        BenchError
            Not a finite number or None.
        """
        self.until = check_until(until)
        self._wake.set()

    def _reached_until(self) -> bool:
        """Whether the session has reached ``until`` (then the clock is held there)."""
        until = self.until
        if until is None or self.session.t < until - 1e-9 * self.session.chunk:
            return False
        self._running = False
        self.until = None
        return True

    def set_rate(self, rate: float) -> None:
        """Model seconds per wall second from now (> 0, ``inf``: unthrottled).

        Raises
        ------
        BenchError
            Not a positive number.
        """
        self.rate = check_rate(rate)
        self._reanchor()
        self._wake.set()

    def _reanchor(self) -> None:
        self._anchor = (time.monotonic(), self.session.t)

    def _due(self) -> float:
        """Wall seconds until the next chunk should start (<= 0: now)."""
        if math.isinf(self.rate):
            return 0.0
        wall0, model0 = self._anchor
        # one chunk ahead: the chunk that starts at t is computed when the clock reaches
        # t - chunk, so its samples are there when the clock shows them
        target = model0 + self.rate * (time.monotonic() - wall0) + self.session.chunk
        return (self.session.t - target) / self.rate

    def _loop(self) -> None:
        while not self._stop.is_set():
            if not self.running or self._reached_until():
                self._wake.wait(0.1)
                self._wake.clear()
                continue
            wait = self._due()
            if wait > 0:
                self._wake.wait(min(wait, 0.1))
                self._wake.clear()
                continue
            t0 = self.session.t
            try:
                self.session.step()
            except Exception as exc:  # noqa: BLE001 - reported through the API, clock stopped
                self.error = chunk_error(exc, t0, self.session.chunk)
            if not math.isinf(self.rate) and self._due() < -1.0:
                self._reanchor()  # more than a second behind: do not race to catch up


def check_rate(rate) -> float:
    """``rate`` as a float if it is a positive number (``inf`` allowed).

    Raises
    ------
    BenchError
    """
    if isinstance(rate, bool) or not isinstance(rate, int | float) or not rate > 0:
        raise BenchError(
            f"rate must be a positive number of model seconds per second, got {rate!r}"
        )
    return float(rate)


def chunk_error(exc: BaseException, t0: float, chunk: float) -> str:
    """The message of a chunk that failed from model time ``t0`` (s): the engine's times
    count from the chunk's start (each chunk is a run from 0), which read alone looked like
    the session's first chunk."""
    return (
        f"{type(exc).__name__} in the chunk from model time {t0:.6g} s to {t0 + chunk:.6g} s "
        f"(the engine's times count from the chunk's start): {exc}"
    )


def check_until(until) -> float | None:
    """``until`` as a float if it is a finite number of model seconds, or None.

    Raises
    ------
    BenchError
    """
    if until is None:
        return None
    if isinstance(until, bool) or not isinstance(until, int | float) or not math.isfinite(until):
        raise BenchError(f"until must be a finite number of model seconds or null, got {until!r}")
    return float(until)
