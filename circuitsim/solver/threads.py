"""Keep OpenBLAS on one thread while the engine runs (threadpoolctl's job, without the dep).

The engine factors many small matrices; OpenBLAS parallelizes ``dgetrf`` from about 100 x 100
up, and on two busy cores the thread hand-offs made one 200 x 200 factorization 0.2 s instead
of 0.7 ms (docs/solver.md). :func:`single_threaded_blas` finds every OpenBLAS library loaded in
the process (numpy's and scipy's wheels each bring one), sets one thread, and restores the
previous count on exit. Where the libraries cannot be found (not Linux, another BLAS) it does
nothing.
"""

from __future__ import annotations

import ctypes
import sys
from collections.abc import Iterator
from contextlib import contextmanager

_PREFIXES = ("scipy_openblas_", "openblas_")
_SUFFIXES = ("64_", "")


# The last scan: (number of imported modules then, controls found). A library is loaded by
# an import, so the scan (reading /proc/self/maps and the libraries' symbols, ~1 ms with
# numba loaded) is repeated only when modules were imported since.
_LAST_SCAN: list = [-1, []]


def _openblas_controls() -> list[tuple[object, object]]:
    """(get, set) function pairs of every loaded OpenBLAS."""
    if _LAST_SCAN[0] != len(sys.modules):
        _LAST_SCAN[:] = [len(sys.modules), _scan()]
    return _LAST_SCAN[1]


def _scan() -> list[tuple[object, object]]:
    try:
        with open("/proc/self/maps") as maps:
            paths = {line.split()[-1] for line in maps if "openblas" in line.lower()}
    except OSError:
        return []
    controls = []
    for path in sorted(paths):
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for prefix in _PREFIXES:
            for suffix in _SUFFIXES:
                get = getattr(lib, f"{prefix}get_num_threads{suffix}", None)
                put = getattr(lib, f"{prefix}set_num_threads{suffix}", None)
                if get is not None and put is not None:
                    get.restype = ctypes.c_int
                    put.argtypes = [ctypes.c_int]
                    controls.append((get, put))
                    break
            else:
                continue
            break
    return controls


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run the body with every loaded OpenBLAS limited to one thread."""
    controls = _openblas_controls()
    saved = []
    for get, put in controls:
        saved.append((put, get()))
        put(1)
    try:
        yield
    finally:
        for put, count in saved:
            put(count)
