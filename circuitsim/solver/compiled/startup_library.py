"""The start-up library: the kernels Python calls, compiled ahead of time (numba.pycc) into
extension modules that a later process loads without importing numba (solver/jit.py).

Built in the process that ran a kernel from numba, from numba's machine code of that process
(about 15-20 s of CPU on the 2-core VM when the kernel is in numba's cache, docs/solver.md), for
the types that process called it with; kept in the user cache directory under the stamp of
solver/jit.py (the solver's sources, Python, numpy, numba and the CPU). One module per kernel:
the ports kernel, the MNA kernel (``compiled``) and the CSV writer. Needs a C compiler and
Python's headers (numba.pycc builds a CPython extension); without them the build is said to
have failed once per process (a StartupLibraryWarning), and runs load numba's kernels as before.
``CIRCUITSIM_NO_STARTUP_LIBRARY=1`` turns it off (neither used nor built).
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import json
import os
import shutil
import sys
import tempfile
import time
import warnings
from pathlib import Path

from circuitsim.atomic import write_text_atomic
from circuitsim.solver import jit
from circuitsim.solver.compiled.cache import (
    kernel_label,
    last_compile_seconds,
    record_compile_seconds,
)
from circuitsim.solver.errors import KernelCompileWarning, StartupLibraryWarning

FIRST_BUILD = "about 20 s"  # the ports kernel's build after its compile, measured: 17-20 s
STALE_AGE = 7 * 86400.0  # s: other stamps' libraries kept this long after their build
_TRIED: set[str] = set()  # kinds whose build was tried in this process


def python_called(kind: str) -> tuple:
    """The numba functions of kernel ``kind`` that Python calls: its entry into the time loop
    and the helpers the runner calls around it."""
    if kind == "CSV writer":
        from circuitsim.solver import float_text

        return (float_text._write_rows,)
    from circuitsim.solver.compiled import (
        fill,
        newton,
        order_cache,
        pivot_search,
        sparse_factors,
        time_loop,
    )

    if kind == "ports":
        return (time_loop.run_ports, newton.dense_factor, *sparse_factors.SPARSE_FUNCTIONS)
    helpers = (order_cache.assemble, order_cache.refactor, order_cache.stamp_terminals)
    return (time_loop.run_mna, *fill.FILL_FUNCTIONS, *pivot_search.SEARCH_FUNCTIONS, *helpers)


def module_name(kind: str) -> str:
    """The extension module of kernel ``kind`` in the library."""
    return jit.MODULE_PREFIX + kind.replace(" ", "_").lower()


def is_built(kind: str) -> bool:
    """Whether the library for the present sources has kernel ``kind``'s module, or a build
    of it failed (its ``.failed`` file says why; not tried again for these sources)."""
    folder = jit.library_folder()
    found = folder.glob(module_name(kind) + ".*")
    return any(is_module(p, kind) or p == failure_path(kind) for p in found)


def failure_path(kind: str) -> Path:
    """The file that keeps why kernel ``kind``'s build failed for the present sources."""
    return jit.library_folder() / f"{module_name(kind)}.failed"


def wanted(kind: str) -> bool:
    """Whether to build ``kind``'s module now: the library is on, this process runs numba's
    kernels, nothing was tried for ``kind`` in it yet, and the module is missing."""
    if jit.disabled() or kind in _TRIED or jit.library_in_use():
        return False
    try:
        built = is_built(kind)
    except OSError:
        built = True
    if built:
        _TRIED.add(kind)  # not looked up again in this process (the stamp hashes the sources)
    return not built


def notice(kind: str) -> str:
    """The one-line announcement of a build of kernel ``kind``'s module, with an estimate
    (the last build's time on this machine, else FIRST_BUILD's)."""
    seconds = last_compile_seconds(timing_key(kind))
    estimate = f"about {seconds:.0f} s" if seconds is not None else FIRST_BUILD
    return (
        f"building the start-up library of the {kernel_label(kind)} kernel (once; {estimate}): "
        "later processes run its machine code without loading numba"
    )


def timing_key(kind: str) -> str:
    """The name of ``kind``'s build in the compile timings (compiled/cache.py)."""
    return f"{kind} start-up library"


def build_when_missing(kind: str) -> Path | None:
    """After a run on numba's kernel ``kind``: its module of the library, when it is
    missing (announced by a KernelCompileWarning, its time kept as the next estimate)."""
    if not wanted(kind):
        return None
    warnings.warn(KernelCompileWarning(notice(kind)), stacklevel=3)
    started = time.perf_counter()
    built = build(kind)
    if built is not None:
        record_compile_seconds(timing_key(kind), time.perf_counter() - started)
    return built


def build(kind: str) -> Path | None:
    """Compile kernel ``kind``'s numba functions called in this process into its module of
    the library (written to a temporary folder, then moved into place). Returns the module's
    path; None when there was nothing to build (no function called yet, or called with more
    than one set of types) or the build failed (said by a StartupLibraryWarning)."""
    _TRIED.add(kind)
    if kind == "ports":  # its sparse factorization, whatever the size of the circuit run
        from circuitsim.solver.compiled.sparse_factors import factor_trial

        factor_trial()
    functions = [f for f in python_called(kind) if getattr(f, "signatures", ())]
    if python_called(kind)[0] not in functions:
        return None  # the entry itself is not compiled in this process
    folder = jit.library_folder()
    log = ""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=".build-", dir=folder) as work:
            try:
                built = _compile(kind, functions, Path(work))
            finally:
                log_path = Path(work) / "build.log"
                log = log_path.read_text(errors="replace") if log_path.exists() else ""
            arguments = built.with_name(module_name(kind) + ".json")
            os.replace(arguments, folder / arguments.name)  # first: the module needs it
            target = folder / built.name
            os.replace(built, target)
    except Exception as error:  # the compiler's errors are many; each means no library
        said = f"{type(error).__name__}: {error}"[:300]
        tail = log.strip().splitlines()[-1][:300] if log.strip() else ""
        reason = said + (f"; {tail}" if tail else "")
        try:
            write_text_atomic(failure_path(kind), reason + "\n" + log[-20_000:])
            retry = f"not tried again for these sources (delete {failure_path(kind)} to retry)"
        except OSError:
            retry = "tried again by the next process"
        warnings.warn(
            StartupLibraryWarning(
                f"the start-up library of the {kernel_label(kind)} kernel could not be built "
                f"({reason}); "
                f"processes load numba's machine code instead (about 0.5 s more at "
                f"start-up); {retry}"
            ),
            stacklevel=3,
        )
        return None
    remove_stale()
    return target


def _compile(kind: str, functions: list, work: Path) -> Path:
    """numba.pycc's build of ``functions``, each of their signatures, in ``work`` (its output
    kept in build.log there, not printed): the module's file."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its pending deprecation (numba 0.57 on; still here)
        from numba.pycc import CC

    cc = CC(module_name(kind))
    cc.output_dir = str(work)
    cc.target_cpu = "host"  # the stamp holds the CPU's flags
    arguments = {}
    for function in functions:
        name = jit.export_name(function.py_func)
        for k, signature in enumerate(function.nopython_signatures):
            try:
                keys = [type_key(t) for t in signature.args]
            except TypeError:  # a type only numba's callers pass: no export for it
                continue
            cc.export(jit.signature_name(name, k), signature)(function.py_func)
            arguments[jit.signature_name(name, k)] = keys
    (work / (module_name(kind) + ".json")).write_text(json.dumps(arguments))
    with _captured_output(work / "build.log"), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numba's pending deprecation of pycc, distutils'
        cc.compile()
    return next(p for p in work.iterdir() if is_module(p, kind))


def is_module(path: Path, kind: str) -> bool:
    """Whether ``path`` is kernel ``kind``'s extension module (any of this Python's suffixes)."""
    suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
    return path.name.startswith(module_name(kind) + ".") and path.name.endswith(suffixes)


def type_key(numba_type) -> list:
    """A numba argument type in solver/jit.py's ``argument_key`` form (what a call's
    arguments are checked against before the library's machine code takes them)."""
    from numba import types
    from numba.np.numpy_support import as_dtype

    if isinstance(numba_type, types.Array):
        dtype = as_dtype(numba_type.dtype).str
        return ["array", dtype, numba_type.ndim, numba_type.layout, bool(numba_type.mutable)]
    if isinstance(numba_type, types.BaseNamedTuple):
        return [numba_type.instance_class.__name__, [type_key(t) for t in numba_type.types]]
    if isinstance(numba_type, types.BaseTuple):
        return ["tuple", [type_key(t) for t in numba_type.types]]
    if isinstance(numba_type, types.Boolean):
        return ["bool"]
    if isinstance(numba_type, types.NoneType):
        return ["none"]
    if isinstance(numba_type, types.Integer | types.Float):
        return [str(numba_type)]
    raise TypeError(f"no start-up library for arguments of type {numba_type}")


@contextlib.contextmanager
def _captured_output(path: Path):
    """Both output streams of this process (the C compiler's too) sent to ``path``."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with open(path, "wb") as log:
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
        try:
            yield log
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            for fd, kept in zip((1, 2), saved, strict=True):
                os.dup2(kept, fd)
                os.close(kept)


def remove_stale(age: float = STALE_AGE) -> None:
    """Drop the libraries of other stamps (earlier sources, another numba ...) not written
    for ``age`` seconds (another checkout sharing the cache keeps its own while in use)."""
    present = jit.library_folder()
    now = time.time()
    for folder in present.parent.glob("*"):
        if folder != present and folder.is_dir() and now - folder.stat().st_mtime > age:
            shutil.rmtree(folder, ignore_errors=True)
