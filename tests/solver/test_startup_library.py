"""The start-up library (solver/jit.py, compiled/startup_library.py): processes that run the
kernels' ahead-of-time machine code without importing numba, with the same results."""

import json
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, jit, simulate
from circuitsim.solver.compiled import startup_library
from circuitsim.solver.errors import StartupLibraryWarning

REPO = Path(__file__).resolve().parents[2]
NO_COMPILER = "no C compiler (numba.pycc builds the start-up library with one; apt-get install gcc)"
WHEELSET = REPO / "netlists" / "wheelset_flange_ideal_ngspice.cir"
TL074_WHEELSET = REPO / "netlists" / "wheelset_flange_tl074_ngspice.cir"

# a process that runs the CLI's simulate, then says whether it imported numba
CLI = """
import sys
from circuitsim.cli import main
code = main(sys.argv[1:])
print("NUMBA-IMPORTED" if "numba" in sys.modules else "NUMBA-NOT-IMPORTED")
print("SCIPY-IMPORTED" if "scipy" in sys.modules else "SCIPY-NOT-IMPORTED")
sys.exit(code)
"""


def _environment(library: bool) -> dict:
    env = dict(os.environ)
    env[jit.DISABLE_ENV] = "0" if library else "1"
    return env


def _simulate_process(tmp_path: Path, name: str, library: bool, *extra: str,
                      netlist: Path = WHEELSET):  # fmt: skip
    out = tmp_path / f"{name}.csv"
    done = subprocess.run(
        [sys.executable, "-c", CLI, "simulate", str(netlist), "--csv", str(out), *extra],
        capture_output=True, text=True, env=_environment(library), timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return out.read_bytes(), done.stdout


@pytest.fixture(scope="module")
def built_library():
    """The ports kernel's and the CSV writer's modules, built in this process from numba's
    kernels (compiled or loaded from the cache by the wheelset's run)."""
    if not any(shutil.which(c) for c in ("cc", "gcc", "clang")):
        pytest.skip(NO_COMPILER)
    circuit = read_netlist(WHEELSET)
    waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
    assert waves.stats["kernel"] == "ports"
    waves.to_csv(Path(os.devnull))  # the writer compiled (or loaded) in this process
    paths = [startup_library.build("ports"), startup_library.build("CSV writer")]
    assert all(p is not None and p.exists() for p in paths), paths
    return paths


def test_a_process_with_the_library_does_not_import_numba_and_writes_the_same_csv(
    built_library, tmp_path
):
    """... nor scipy: the ideal wheelset (54 unknowns, a uic start) is assembled densely,
    and the ports kernel inverts its matrix by loops of its own (numba's LAPACK would import
    scipy.linalg at the first factorization); numba's kernels import scipy themselves."""
    with_library, said = _simulate_process(tmp_path, "library", library=True)
    assert "NUMBA-NOT-IMPORTED" in said and "SCIPY-NOT-IMPORTED" in said
    without, said_without = _simulate_process(tmp_path, "numba", library=False)
    assert "NUMBA-IMPORTED" in said_without
    assert with_library == without  # byte for byte: the same machine code's results
    assert with_library.count(b"\n") > 18_000  # the wheelset's 18,581 time points


def test_a_large_circuit_runs_on_a_library_built_after_a_small_one(built_library, tmp_path):
    """The TL074 wheelset (266 unknowns, above sparse_factors.SPARSE_FROM) on the ports
    module built after the ideal wheelset's dense run: its sparse factorizations' helpers are
    in the module (the build's trial), so the process imports neither numba nor scipy, and
    writes what numba's kernels write."""
    probe = ("--probe", "v(y)")
    with_library, said = _simulate_process(tmp_path, "library", True, *probe,
                                           netlist=TL074_WHEELSET)  # fmt: skip
    assert "NUMBA-NOT-IMPORTED" in said and "SCIPY-NOT-IMPORTED" in said
    without, said_without = _simulate_process(tmp_path, "numba", False, *probe,
                                              netlist=TL074_WHEELSET)  # fmt: skip
    assert "NUMBA-IMPORTED" in said_without
    assert with_library == without
    assert with_library.count(b"\n") > 18_000


def test_a_kernel_the_library_lacks_runs_on_numba_then_joins_it(built_library, tmp_path):
    """Another kernel than the library's (the MNA kernel): numba's, with its results; that
    process builds its module, and the next one runs it without numba (its helpers, called
    from Python at new pivot orders, included)."""
    for path in jit.library_folder().glob(startup_library.module_name("compiled") + ".*"):
        path.unlink()  # built by an earlier run of this test
    without, _ = _simulate_process(tmp_path, "numba", False, "--kernel", "compiled")
    first, said = _simulate_process(tmp_path, "first", True, "--kernel", "compiled")
    assert "NUMBA-IMPORTED" in said
    assert first == without
    assert startup_library.is_built("compiled")
    second, said = _simulate_process(tmp_path, "second", True, "--kernel", "compiled")
    # nor scipy: the pivot orders are our own search's (compiled/pivot_search.py)
    assert "NUMBA-NOT-IMPORTED" in said and "SCIPY-NOT-IMPORTED" in said
    assert second == without


def test_the_library_is_keyed_by_the_sources(monkeypatch, tmp_path):
    (tmp_path / "solver").mkdir()
    source = tmp_path / "solver" / "kernel.py"
    source.write_text("x = 1\n")
    monkeypatch.setattr(jit, "SOLVER", tmp_path / "solver")
    before = jit.source_stamp()
    assert jit.source_stamp() == before
    source.write_text("x = 2\n")
    assert jit.source_stamp() != before
    monkeypatch.setenv("CIRCUITSIM_CACHE_DIR", str(tmp_path / "cache"))
    assert jit.library_folder().parent == tmp_path / "cache" / "startup"


def test_a_failed_build_is_said_and_leaves_nothing(monkeypatch, tmp_path, built_library):
    """No C compiler (or any failure of numba.pycc): a StartupLibraryWarning that names the
    kernel and the error; no file of the failed build left behind."""
    monkeypatch.setenv("CIRCUITSIM_CACHE_DIR", str(tmp_path))

    def no_compiler(kind, functions, work):
        (work / "build.log").write_text("gcc: command not found\n")
        raise RuntimeError("the C compiler failed")

    monkeypatch.setattr(startup_library, "_compile", no_compiler)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert startup_library.build("ports") is None
    said = [str(w.message) for w in caught if issubclass(w.category, StartupLibraryWarning)]
    assert len(said) == 1
    assert "ports kernel" in said[0] and "the C compiler failed" in said[0]
    assert "gcc: command not found" in said[0]
    # the build folder is gone; the reason is kept, and the build not tried again
    assert [p.name for p in jit.library_folder().iterdir()] == [
        startup_library.failure_path("ports").name
    ]
    assert "the C compiler failed" in startup_library.failure_path("ports").read_text()
    monkeypatch.setattr(startup_library, "_TRIED", set())
    monkeypatch.setattr(jit, "library_in_use", lambda: False)
    assert not startup_library.wanted("ports")


def test_the_library_is_off_when_asked(monkeypatch):
    monkeypatch.setenv(jit.DISABLE_ENV, "1")
    assert jit.disabled()
    assert not startup_library.wanted("ports")
    monkeypatch.setenv(jit.DISABLE_ENV, "0")
    assert not jit.disabled()


def test_runs_on_threads_leave_the_library(built_library, tmp_path):
    """The library's functions hold the interpreter lock: variants on two threads run numba's
    kernels (which release it), with the same results as one by one."""
    script = f"""
import json, sys
from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, jit
from circuitsim.solver.variants import simulate_variants
circuit = read_netlist({str(WHEELSET)!r})
before = jit.library_in_use()
one, two = simulate_variants([circuit, circuit], ["v(y)"], workers=2)
same = bool((one["v(y)"] == two["v(y)"]).all())
print(json.dumps([before, jit.library_in_use(), "numba" in sys.modules, same]))
"""
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True,
        env=_environment(True), timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == [True, False, True, True]


def test_the_library_takes_only_the_types_it_was_built_for():
    """pycc's machine code reads an argument's memory unchecked (a float32 table in place of
    a float64 one crashed the process): each call's arguments are checked first."""
    import numpy as np

    table = np.zeros((3, 2))
    key = jit.argument_key(table)
    assert key == ["array", "<f8", 2, "C", True]
    assert jit.takes(key, np.ones((5, 2)))  # other sizes: the same type
    assert not jit.takes(key, table.astype(np.float32))
    assert not jit.takes(key, np.zeros(3))  # other dimensions
    assert not jit.takes(key, np.asfortranarray(np.zeros((3, 2))))
    frozen = np.zeros((3, 2))
    frozen.flags.writeable = False
    assert not jit.takes(key, frozen)  # the code may write into it
    assert jit.takes(["array", "<f8", 2, "A", False], np.asfortranarray(frozen))
    pair = (table, 1.5)
    assert jit.takes(jit.argument_key(pair), (np.ones((1, 2)), 2.0))
    assert not jit.takes(jit.argument_key(pair), (np.ones((1, 2)), 2))  # an int for a float
    assert not jit.takes(jit.argument_key(pair), (np.ones((1, 2)),))
    assert not jit.takes(jit.argument_key(pair), [np.ones((1, 2)), 2.0])  # not a tuple
    assert jit.takes(["bool"], True) and not jit.takes(["int64"], True)
