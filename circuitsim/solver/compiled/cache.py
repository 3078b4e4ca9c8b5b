"""Where the compiled kernels' machine code is kept, and whether a run must compile first.

numba compiles the kernels on their first use and caches the machine code. By default it
would write it beside the sources (``__pycache__`` in the installed package, often read-only)
or in a folder of its own; here it goes to a user cache directory:
``$CIRCUITSIM_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/circuitsim`` (``~/.cache/circuitsim``),
with a sub-folder per source folder (numba's own naming: the folder's name and a hash of its
path, so two checkouts never share machine code). A folder that cannot be written falls back
to numba's own locations.

numba's cache checks only the file a function is defined in, so a cached ``run`` would keep
the old code of a changed ``newton`` compiled into it: :func:`clear_stale_cache` keeps a stamp
of every kernel source and drops the machine code when any of them changed.
"""

from __future__ import annotations

import hashlib
import json
import sys
import threading
from pathlib import Path

from circuitsim.atomic import write_text_atomic
from circuitsim.solver.cache_dir import CACHE_ENV, cache_root  # noqa: F401 (re-exported)

# reference-engine files whose constants the kernels compile in (numba freezes globals)
CONSTANT_SOURCES = ("port_solver.py", "transient.py")
PACKAGE = "circuitsim."
# the modules whose numba functions make up the kernels (their sources' stamp: check_cache)
KERNEL_PACKAGES = ("circuitsim.solver.compiled", "circuitsim.solver.devices")

_LOCK = threading.Lock()
_WRITABLE: set[str] = set()  # cache folders found writable in this process
_PREPARED: list[bool] = []


def numba_folder() -> Path:
    """Where numba's index (.nbi) and machine-code (.nbc) files go."""
    return cache_root() / "numba"


def _locator_classes():
    """numba's cache locator for our kernels (first), then numba's own as the fallback."""
    from numba.core import caching

    class KernelCacheLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
        """numba's user-provided-directory locator, with our directory."""

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = str(numba_folder() / self.get_suitable_cache_subpath(py_file))

        def get_cache_path(self):
            return self._cache_path

        def ensure_cache_path(self):
            # numba writes and deletes a test file per function; once per folder is enough
            if self._cache_path not in _WRITABLE:
                super().ensure_cache_path()
                _WRITABLE.add(self._cache_path)

    return [KernelCacheLocator, *caching.CompileResultCacheImpl._locator_classes]


def relocate_caches(names: list[str] | None = None) -> list:
    """Point every not yet used numba function of this package (or of the modules ``names``)
    at :func:`numba_folder`.

    Done per function (a cache object of its own), so numba's defaults for other packages
    stay as they are. Returns the cache objects, one per function.
    """
    from numba.core import caching
    from numba.core.registry import CPUDispatcher
    from numba.core.runtime.nrt import rtsys

    class KernelCacheImpl(caching.CompileResultCacheImpl):
        _locator_classes = _locator_classes()

    class KernelFunctionCache(caching.FunctionCache):
        """numba's cache of one function, loading without refreshing the target context.

        numba refreshes the whole target context before it loads machine code: it imports
        and installs every typing and lowering registry (numpy ufuncs, linalg, typed
        containers ...), about 0.2 s of a process's start, which only compiling needs
        (compiling refreshes by itself). Running loaded nopython code needs numba's runtime
        (NRT) only. Functions compiled with ``parallel=True`` are loaded numba's way.
        """

        _impl_class = KernelCacheImpl

        def __init__(self, py_func, parallel: bool = False):
            super().__init__(py_func)
            self._parallel = parallel

        def load_overload(self, sig, target_context):
            if self._parallel:
                return super().load_overload(sig, target_context)
            rtsys.initialize(target_context)
            with self._guard_against_spurious_io_errors():
                return self._load_overload(sig, target_context)

    caches = []
    chosen = names if names is not None else [n for n in sys.modules if n.startswith(PACKAGE)]
    for name in chosen:
        module = sys.modules.get(name)
        if module is None:
            continue
        for obj in list(vars(module).values()):
            if not isinstance(obj, CPUDispatcher) or obj.py_func.__module__ != name:
                continue
            if isinstance(getattr(obj, "_cache", None), caching.FunctionCache):
                if not isinstance(obj._cache, KernelFunctionCache) and not obj.overloads:
                    parallel = bool(obj.targetoptions.get("parallel"))
                    obj._cache = KernelFunctionCache(obj.py_func, parallel)
                caches.append(obj._cache)
    return caches


def clear_stale_cache(sources: list[Path], folders: list[Path], stamp: Path) -> bool:
    """Delete the machine code in ``folders`` when any of ``sources`` changed since ``stamp``
    was written (a digest of them all). Returns True when cache files were deleted."""
    digest = hashlib.sha256()
    for source in sorted(set(sources)):
        if source.exists():
            digest.update(str(source.name).encode())
            digest.update(source.read_bytes())
    try:
        if stamp.read_text() == digest.hexdigest():
            return False
    except OSError:
        pass
    removed = False
    try:
        for folder in set(folders):
            for path in [*folder.glob("*.nbi"), *folder.glob("*.nbc")]:
                path.unlink(missing_ok=True)
                removed = True
        stamp.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(stamp, digest.hexdigest())
    except OSError:
        return False
    return removed


def check_cache() -> None:
    """Once per process, before the first kernel call: the kernels' numba functions use the
    user cache directory, and machine code older than any kernel source is dropped. Imports
    the kernel modules (and numba)."""
    from circuitsim.solver.jit import library_in_use

    if library_in_use():  # the start-up library's machine code: built for these sources
        return
    with _LOCK:
        if _PREPARED:
            return
        from circuitsim.solver.compiled import time_loop  # noqa: F401

        kernel_modules = [n for n in sys.modules if n.startswith(KERNEL_PACKAGES)]
        caches = relocate_caches(kernel_modules)
        sources = {Path(sys.modules[c._py_func.__module__].__file__) for c in caches}
        folder = Path(time_loop.__file__).resolve().parent
        sources |= {folder.parent / name for name in CONSTANT_SOURCES}
        cache_folders = [Path(c._cache_path) for c in caches]
        key = hashlib.sha1(str(folder).encode()).hexdigest()[:16]
        clear_stale_cache(sorted(sources), cache_folders, numba_folder() / f"sources-{key}.sha256")
        _PREPARED.append(True)


def _on_numba() -> None:
    """When a process leaves the start-up library for numba (solver/jit.py): numba's kernels
    use the user cache directory, as in any other process."""
    check_cache()


def is_cold(dispatcher) -> bool:
    """Whether calling ``dispatcher`` (a numba function) must compile: nothing compiled in
    this process and nothing usable in its disk cache, nor in the start-up library."""
    from circuitsim.solver.jit import LazyKernel

    if isinstance(dispatcher, LazyKernel):
        if dispatcher.compiled and dispatcher.dispatcher is None:
            return False
        dispatcher = dispatcher.numba_function()
    if dispatcher.overloads:
        return False
    cache = getattr(dispatcher, "_cache", None)
    cache_file = getattr(cache, "_cache_file", None)
    if cache_file is None:
        return True
    try:
        return not cache_file._load_index()
    except Exception:  # an unreadable index: numba will recompile (and rewrite it)
        return True


# the estimate of a kernel's first compile on a machine, before it has timed one: cold
# compiles measured on the 2-core VM (docs/performance.md): the ports kernel 155-195 s, the
# MNA kernel ("compiled") about 90 s of CPU; the CSV writer 8 s
FIRST_COMPILE = {
    "ports": "about 3 minutes",
    "compiled": "about a minute and a half",
    "CSV writer": "about 10 seconds",
}


def _timings_path() -> Path:
    return cache_root() / "compile-seconds.json"


def last_compile_seconds(kind: str) -> float | None:
    """How long the last compile of kernel ``kind`` took on this machine, s (None: unknown)."""
    try:
        return float(json.loads(_timings_path().read_text())[kind])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def record_compile_seconds(kind: str, seconds: float) -> None:
    """Keep ``seconds`` as the estimate of kernel ``kind``'s next compile."""
    path = _timings_path()
    try:
        table = json.loads(path.read_text())
        if not isinstance(table, dict):
            table = {}
    except (OSError, ValueError):
        table = {}
    table[kind] = round(seconds, 1)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text_atomic(path, json.dumps(table))
    except OSError:
        pass


def kernel_label(kind: str) -> str:
    """A kernel's name in messages: "MNA" for ``kernel="compiled"`` (the option's value)."""
    return "MNA" if kind == "compiled" else kind


def compile_notice(kind: str) -> str:
    """The one-line announcement of a cold compile of kernel ``kind``, with an estimate."""
    seconds = last_compile_seconds(kind)
    estimate = (
        f"the last compile on this machine took {seconds:.0f} s"
        if seconds is not None
        else FIRST_COMPILE.get(kind, "up to a minute") + ", longer on a loaded machine"
    )
    return (
        f"compiling the {kernel_label(kind)} kernel (its first use since it was installed or "
        f"changed; {estimate}); the machine code is then cached in {numba_folder()}"
    )
