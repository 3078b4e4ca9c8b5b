"""The kernels' decorator: numba's ``njit``, or the start-up library's machine code.

Importing numba and loading its cached machine code costs a ``simulate`` process about 0.5 s
of CPU (docs/performance.md, section 6), more than the ideal wheelset's whole solve. So the
kernels that Python calls are also compiled ahead of time into extension modules, the
start-up library (compiled/startup_library.py builds it after numba has compiled the
kernels once), kept in the user cache directory under a stamp of everything the machine
code depends on: circuitsim's solver sources, Python, numpy and numba, the CPU.

When a library for the present stamp exists (and ``CIRCUITSIM_NO_STARTUP_LIBRARY`` is not
set), :func:`njit` returns a :class:`LazyKernel` in place of a numba function: a call from
Python runs the library's machine code, and numba is not imported. A call the library cannot
take (a function it does not export, or argument types other than the ones it was built
for) and any use that needs numba's function itself (compiling a caller, its cache)
turns every lazy kernel into numba's function first (:func:`use_numba`): the process then
runs exactly as without a library. Without a library :func:`njit` is numba's ``njit``.

The library's functions hold Python's global interpreter lock while they run (numba's
``nogil`` kernels release it): runs on several threads call :func:`use_numba` first.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import json
import os
import platform
import sys
import threading
from pathlib import Path

import numpy as np

from circuitsim.solver.cache_dir import cache_root

DISABLE_ENV = "CIRCUITSIM_NO_STARTUP_LIBRARY"
MODULE_PREFIX = "circuitsim_kernels_"  # the library's modules: circuitsim_kernels_<kind>
SOLVER = Path(__file__).resolve().parent  # the sources the machine code is built from

_LOCK = threading.RLock()
_LAZY: list[LazyKernel] = []
_STATE: dict = {"modules": None, "numba": False}


def source_stamp() -> str:
    """A hash of what the library's machine code depends on: every source file of the solver,
    the Python, numpy and numba installations, and this CPU (its flags: the code is built
    for the host's instruction set)."""
    digest = hashlib.sha256()
    for path in sorted(SOLVER.rglob("*.py")):
        digest.update(str(path.relative_to(SOLVER)).encode())
        digest.update(path.read_bytes())
    numba_spec = importlib.util.find_spec("numba")
    numba_origin = Path(numba_spec.origin) if numba_spec and numba_spec.origin else None
    numba_id = ""
    if numba_origin is not None:
        version = numba_origin.parent / "_version.py"
        numba_id = version.read_text() if version.exists() else str(numba_origin.stat().st_mtime)
    digest.update(f"{sys.version}|{np.__version__}|{numba_id}|{_cpu_id()}".encode())
    return digest.hexdigest()[:20]


def _cpu_id() -> str:
    """This machine's processor: model and instruction-set flags where Linux tells them."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return f"{platform.machine()}|{platform.processor()}"
    wanted = ("model name", "flags", "Features", "CPU part")
    found = {}
    for line in lines:
        key = line.split(":", 1)[0].strip()
        if key in wanted and key not in found:
            found[key] = line.split(":", 1)[1].strip()
    return f"{platform.machine()}|{sorted(found.items())}"


def library_folder(stamp: str | None = None) -> Path:
    """Where the start-up library for ``stamp`` (default: the present one) is kept."""
    return cache_root() / "startup" / (stamp or source_stamp())


def _library_modules() -> list:
    """The start-up library's modules for the present stamp, loaded (none: no library)."""
    if _STATE["modules"] is None:
        modules = []
        if not disabled():
            try:
                folder = library_folder()
            except OSError:
                folder = None
            if folder is not None and folder.is_dir():
                paths = sorted(folder.glob(MODULE_PREFIX + "*"))
                suffixes = tuple(importlib.machinery.EXTENSION_SUFFIXES)
                modules = [_load(path) for path in paths if path.name.endswith(suffixes)]
                modules = [m for m in modules if m is not None]
        _STATE["modules"] = modules
    return _STATE["modules"]


def _load(path: Path):
    """One extension module of the library, with the argument types of its functions (the
    JSON file beside it: ``ARGUMENTS``), or None when either does not load."""
    name = path.name.split(".", 1)[0]
    try:
        arguments = json.loads(path.with_name(name + ".json").read_text())
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except (ImportError, OSError, ValueError):
        return None
    module.ARGUMENTS = arguments
    return module


def argument_key(value):
    """What a function of the library needs to know of an argument to take it: an array's
    dtype, dimensions, layout and writability; a tuple's class and items; a scalar's type
    (as numba types them: a Python int is int64, a float float64)."""
    if isinstance(value, np.ndarray):
        layout = "C" if value.flags.c_contiguous else "F" if value.flags.f_contiguous else "A"
        return ["array", value.dtype.str, value.ndim, layout, bool(value.flags.writeable)]
    if isinstance(value, tuple):
        return [type(value).__name__, [argument_key(item) for item in value]]
    if isinstance(value, bool | np.bool_):
        return ["bool"]
    if isinstance(value, int):
        return ["int64"]
    if isinstance(value, float):
        return ["float64"]
    if isinstance(value, np.generic):
        return [value.dtype.name]
    if value is None:
        return ["none"]
    return ["python", type(value).__name__]


def takes(key, value) -> bool:
    """Whether an argument of the library's type ``key`` (:func:`argument_key`'s form, with
    layout "A" for any) can be ``value``: the machine code reads its memory as that type
    unchecked, so a wrong one would crash the process."""
    found = argument_key(value) if not isinstance(value, tuple) else None
    if key[0] == "array":
        return (
            found is not None and found[:3] == key[:3] and key[3] in ("A", found[3])
            and (found[4] or not key[4])
        )  # fmt: skip
    if isinstance(value, tuple):
        items = key[1] if len(key) == 2 and isinstance(key[1], list) else None
        return (
            items is not None and key[0] == type(value).__name__ and len(items) == len(value)
            and all(takes(k, v) for k, v in zip(items, value, strict=True))
        )  # fmt: skip
    return found == key


def disabled() -> bool:
    """Whether ``CIRCUITSIM_NO_STARTUP_LIBRARY`` turns the library off (set, and not 0)."""
    return os.environ.get(DISABLE_ENV, "0") not in ("", "0")


def export_name(py_func) -> str:
    """The name of ``py_func``'s machine code in the library: module and function."""
    return f"{py_func.__module__.replace('.', '_')}__{py_func.__name__}"


def signature_name(name: str, k: int) -> str:
    """The library's name of signature ``k`` of the function exported as ``name``."""
    return name if k == 0 else f"{name}__{k}"


def numba_installed() -> bool:
    """Whether numba can be imported (looked up, not imported: the library needs none)."""
    return importlib.util.find_spec("numba") is not None


def library_in_use() -> bool:
    """Whether this process runs kernels from the start-up library (numba not yet needed)."""
    with _LOCK:
        return not _STATE["numba"] and bool(_library_modules())


class LazyKernel:
    """A kernel whose Python calls run the start-up library's machine code; numba's function
    (made by :func:`use_numba`) for anything else.

    Parameters
    ----------
    py_func : function
        The kernel's Python source function.
    options : dict
        Its ``njit`` options (cache, inline, nogil ...).
    """

    def __init__(self, py_func, options: dict):
        self.py_func = py_func
        self.options = options
        self.dispatcher = None
        name = export_name(py_func)
        # (machine code, argument types) of each signature the library has of it
        self.library_code = [
            (getattr(m, signature_name(name, k)), m.ARGUMENTS[signature_name(name, k)])
            for m in _library_modules()
            for k in range(len(m.ARGUMENTS))
            if signature_name(name, k) in m.ARGUMENTS and hasattr(m, signature_name(name, k))
        ]
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        _LAZY.append(self)

    def numba_function(self):
        """numba's function of this kernel (every lazy kernel becomes numba's first)."""
        if self.dispatcher is None:
            use_numba()
        return self.dispatcher

    @property
    def compiled(self) -> bool:
        """Whether the library has machine code of this kernel (for some argument types)."""
        return bool(self.library_code)

    def __call__(self, *args):
        if self.dispatcher is None:
            for function, keys in self.library_code:
                if len(keys) == len(args) and all(map(takes, keys, args)):
                    return function(*args)
        return self.numba_function()(*args)

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.numba_function(), name)

    def __repr__(self) -> str:
        return f"<LazyKernel {self.__module__}.{self.__qualname__}>"


def use_numba() -> None:
    """From now on, numba's functions: each lazy kernel becomes numba's function (put in its
    place in every module of the package), and the modules that register with numba do so
    (their ``_on_numba``)."""
    with _LOCK:
        if _STATE["numba"]:
            return
        import numba
        from numba.core.typing.typeof import typeof_impl

        for kernel in _LAZY:
            kernel.dispatcher = numba.njit(**kernel.options)(kernel.py_func)

        @typeof_impl.register(LazyKernel)
        def _typeof_lazy(value, context):  # a lazy kernel left in a container
            return typeof_impl(value.numba_function(), context)

        _STATE["numba"] = True
        modules = [m for n, m in list(sys.modules.items()) if n.startswith("circuitsim") and m]
        for module in modules:
            for key, value in list(vars(module).items()):
                if isinstance(value, LazyKernel):
                    setattr(module, key, value.dispatcher)
        for module in modules:  # each module's registration with numba, once all are numba's
            hook = vars(module).get("_on_numba")
            if callable(hook):
                hook()


def njit(*args, **options):
    """numba's ``njit`` (``@njit`` or ``@njit(**options)``), or a :class:`LazyKernel` while
    this process runs the start-up library."""
    if not library_in_use():
        from numba import njit as numba_njit

        return numba_njit(*args, **options)
    if args and callable(args[0]):
        return LazyKernel(args[0], options)
    return lambda py_func: LazyKernel(py_func, options)
