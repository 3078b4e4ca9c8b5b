"""Ctrl-C (and SIGTERM) while numba compiles the kernels: the process ends at once.

Python runs a signal's handler only between two bytecodes of the main thread. numba's compile
of a kernel ends in llvmlite's C++ library (LLVM optimizing the kernel's module and generating
its machine code: calls that last tens of seconds on a loaded machine), and a SIGINT that comes
meanwhile waits until that call returns: 30 s measured on this 2-core machine. One that comes in
numba's Python part raises KeyboardInterrupt inside numba's compiler, which can leave it half
built (one run here ended in a traceback, "RuntimeError: no compiled object yet for <Library
'factor_now'>", instead of "interrupted"). A compile has nothing to clean up (numba writes its
cache through temporary names and renames), so during one the signal ends the process at once,
with a line on stderr and the usual exit code (130, 143); a compile starts over on the next run.

Two paths see the signal: the main thread's handler (when the main thread runs Python), and a
watcher thread woken by :func:`signal.set_wakeup_fd` (written by the C-level handler at once,
even while the main thread is inside LLVM). Outside a compile nothing changes: SIGINT raises
KeyboardInterrupt in the main thread, whose ``finally`` blocks run.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator

# numba's dispatcher frames of a compile (or of a load from its cache, which starts the same
# way): any thread inside one is making kernels ready
_COMPILE_FRAMES = frozenset(
    {("numba.core.dispatcher", "_compile_for_args"), ("numba.core.dispatcher", "compile")}
)
_WORDS = {signal.SIGINT: ("interrupted", 130), signal.SIGTERM: ("terminated", 143)}


def in_compile(frame) -> bool:
    """Whether ``frame`` or a frame that called it is numba's dispatcher compiling."""
    while frame is not None:
        if (frame.f_globals.get("__name__"), frame.f_code.co_name) in _COMPILE_FRAMES:
            return True
        frame = frame.f_back
    return False


def compiling() -> bool:
    """Whether any thread of this process is inside a numba compile now."""
    return any(in_compile(frame) for frame in sys._current_frames().values())


def stop_if_compiling(signum: int) -> None:
    """End the process at once (exit code 130 for SIGINT, 143 for SIGTERM) when a thread is
    inside a numba compile; else return."""
    if not compiling():
        return
    word, code = _WORDS.get(signum, ("interrupted", 130))
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):  # a closed pipe: the line below still goes out
            stream.flush()
    message = (
        f"{word} while numba was compiling the kernels (a compile cannot stop midway: the "
        "process ends here; the compile starts over on the next run)\n"
    )
    with contextlib.suppress(OSError):
        os.write(2, message.encode())
    os._exit(code)


def _on_sigint(signum: int, frame) -> None:
    stop_if_compiling(signum)
    raise KeyboardInterrupt


def _watch(read_end: int) -> None:
    """Wait for the signal numbers the C-level handler writes; act on those of a compile."""
    with os.fdopen(read_end, "rb", buffering=0) as pipe:
        while chunk := pipe.read(64):
            for signum in chunk:
                if signum in _WORDS:
                    stop_if_compiling(signum)


@contextlib.contextmanager
def prompt_during_compile() -> Iterator[None]:
    """Inside, SIGINT and SIGTERM during a numba compile end the process at once (see the
    module's docstring); outside a compile SIGINT raises KeyboardInterrupt as usual. Only
    in the main thread (the only one that may set signal handlers); elsewhere it does
    nothing. The previous handler and wakeup fd are back on leaving."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)  # the C-level handler must never block on it
    try:
        previous_fd = signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    except (ValueError, OSError):  # a platform whose wakeup fd must be a socket
        os.close(read_end)
        os.close(write_end)
        previous_fd = None
    if previous_fd is not None:
        threading.Thread(
            target=_watch, args=(read_end,), name="circuitsim-signal-watch", daemon=True
        ).start()
    previous_handler = signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous_handler)
        if previous_fd is not None:
            signal.set_wakeup_fd(previous_fd)
            os.close(write_end)  # the watcher reads the end of the pipe and stops
