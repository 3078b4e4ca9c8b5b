"""Where the kernels' machine code is kept, the compile announcement and the fallback warning."""

import warnings
from pathlib import Path

import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.errors import KernelCompileWarning, KernelFallbackWarning

pytest.importorskip("numba")

RECTIFIER = """* cache
V1 in 0 SIN(0 1 1k)
R1 in a 1k
D1 a b DX
C1 b 0 1u
.model DX D(is=1e-14)
.tran 10u 2m
.end
"""


def test_cache_directory_follows_the_environment(monkeypatch, tmp_path):
    from circuitsim.solver.compiled.cache import cache_root

    monkeypatch.delenv("CIRCUITSIM_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "circuitsim"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/ignored")  # the spec: absolute paths only
    assert cache_root() == Path.home() / ".cache" / "circuitsim"
    monkeypatch.setenv("CIRCUITSIM_CACHE_DIR", str(tmp_path / "mine"))
    assert cache_root() == tmp_path / "mine"


def test_kernels_are_cached_outside_the_package():
    import circuitsim
    from circuitsim.solver.compiled import time_loop
    from circuitsim.solver.compiled.cache import cache_root, is_cold

    simulate(parse_netlist(RECTIFIER))
    folder = Path(time_loop.run_ports._cache._cache_path)
    assert folder.is_relative_to(cache_root())
    assert not folder.is_relative_to(Path(circuitsim.__file__).parent)
    assert list(folder.glob("time_loop.run_ports-*.nbi"))
    assert not is_cold(time_loop.run_ports)


def test_a_cold_compile_is_announced_once(monkeypatch):
    from circuitsim.solver.compiled import runner

    monkeypatch.setattr(runner, "is_cold", lambda dispatcher: True)
    monkeypatch.setattr(runner, "_ANNOUNCED", set())
    monkeypatch.setattr(runner, "record_compile_seconds", lambda kind, seconds: None)
    circuit = parse_netlist(RECTIFIER)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulate(circuit)
        simulate(circuit)
    notices = [w for w in caught if issubclass(w.category, KernelCompileWarning)]
    assert len(notices) == 1
    assert "compiling the ports kernel" in str(notices[0].message)
    assert "cached in" in str(notices[0].message)


def test_the_compile_notice_estimates_each_kernel(monkeypatch, tmp_path):
    """Before a machine has timed a compile, each kernel's notice gives its own measured
    estimate (the ports kernel compiles for minutes, not "about a minute"); after, the
    machine's last time."""
    from circuitsim.solver.compiled.cache import compile_notice, record_compile_seconds
    from circuitsim.solver.float_text import COMPILE_KIND
    from circuitsim.solver.options import KERNELS

    monkeypatch.setenv("CIRCUITSIM_CACHE_DIR", str(tmp_path))
    kinds = [k for k in KERNELS if k not in ("auto", "python")] + [COMPILE_KIND]
    assert "about 3 minutes" in compile_notice("ports")
    assert "compiling the MNA kernel" in compile_notice("compiled")  # not "compiled kernel"
    assert "about a minute and a half" in compile_notice("compiled")
    assert "about 10 seconds" in compile_notice(COMPILE_KIND)
    for kind in kinds:
        record_compile_seconds(kind, 123.4)
        assert "the last compile on this machine took 123 s" in compile_notice(kind)


def test_falling_back_to_the_numpy_loop_says_why():
    circuit = parse_netlist(RECTIFIER)
    options = SimulationOptions.from_circuit(circuit, bypass=1)  # no compiled bypass
    with pytest.warns(KernelFallbackWarning, match="numpy reference loop"):
        waves = simulate(circuit, options)
    assert waves.stats["kernel"].startswith("python (")


LOADED_RUN = """
import sys
import numpy as np
from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import simulate
from circuitsim.solver.compiled import time_loop
waves = simulate(parse_netlist(sys.argv[1]))
from numba.core.imputils import builtin_registry
from numba.core.registry import cpu_target
hits = sum(time_loop.run_ports.stats.cache_hits.values())
np.savez(sys.argv[2], time=waves.time, v=waves["v(b)"])
print(hits, builtin_registry in cpu_target.target_context._registries)
"""


def test_a_new_process_loads_the_kernel_without_numbas_registries(tmp_path):
    # the machine code is loaded with numba's runtime only (cache.py: KernelFunctionCache),
    # not after importing every typing and lowering registry, and it computes the same run
    import subprocess
    import sys

    import numpy as np

    waves = simulate(parse_netlist(RECTIFIER))  # in the cache from here on
    out = tmp_path / "loaded.npz"
    done = subprocess.run(
        [sys.executable, "-c", LOADED_RUN, RECTIFIER, str(out)],
        capture_output=True,
        text=True,
        cwd=Path(__file__).resolve().parents[2],
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    hits, registries = done.stdout.split()
    assert int(hits) == 1 and registries == "False"
    loaded = np.load(out)
    assert np.array_equal(loaded["time"], waves.time)
    assert np.array_equal(loaded["v"], waves["v(b)"])
