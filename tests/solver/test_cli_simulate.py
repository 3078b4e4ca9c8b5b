"""`circuitsim simulate`: CSV on the solver's time points, probes, plots, clear failures."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.solver.waveforms import Waveforms
from tests.solver.conftest import requires_ngspice

GOLDEN = Path(__file__).parent / "golden"


def test_csv_header_and_rc_values(tmp_path, capsys):
    out = tmp_path / "rc.csv"
    assert main(["simulate", str(GOLDEN / "rc.cir"), "--csv", str(out)]) == 0
    assert out.read_text().splitlines()[0] == "time,v(in),v(out),i(v1)"
    w = Waveforms.from_csv(out)
    # after the pulse edge at 0.1 ms (rise 1 us) v(out) follows 1 - exp(-t/RC), RC = 1 ms
    t = w.time
    late = (t > 0.2e-3) & (t < 2.1e-3)
    exact = 1 - np.exp(-(t[late] - 0.1e-3 - 0.5e-6) / 1e-3)
    assert np.max(np.abs(w["v(out)"][late] - exact)) < 1e-3
    assert np.all(np.diff(t) > 0) and len(t) > 100
    captured = capsys.readouterr()
    assert "accepted" in captured.out
    # (no progress line for a run shorter than a second: a wall-clock matter, checked with a
    # fake clock by the next test, not here, where a loaded machine takes longer)


def test_progress_after_stays_silent_then_reports(capsys, monkeypatch):
    from circuitsim.cli import common

    clock = iter([100.0, 100.5, 101.2])  # creation, then two reports
    monkeypatch.setattr(common, "time", SimpleNamespace(monotonic=lambda: next(clock)))
    report = common.progress_after(1.0)
    report("early")
    report("late")
    assert capsys.readouterr().err == "late\n"


def test_probe_and_plot(tmp_path):
    csv, png = tmp_path / "n.csv", tmp_path / "n.png"
    args = ["simulate", str(GOLDEN / "nested.cir"), "--probe", "v(out)", "i(v1)"]
    assert main([*args, "--csv", str(csv), "--plot", str(png)]) == 0
    assert csv.read_text().splitlines()[0] == "time,v(out),i(v1)"
    assert png.stat().st_size > 1000


def test_unknown_probe_fails(capsys):
    assert main(["simulate", str(GOLDEN / "rc.cir"), "--probe", "v(nowhere)"]) == 2
    assert "v(nowhere)" in capsys.readouterr().err


def test_singular_circuit_is_one_line_and_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.cir"
    bad.write_text("floating\nV1 a 0 1\nR1 a 0 1k\nC1 a b 1n\nC2 b 0 1n\n.op\n.end\n")
    assert main(["simulate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "singular" in err and "v(b)" in err


@requires_ngspice
def test_ngspice_engine(tmp_path):
    out = tmp_path / "ng.csv"
    assert main(["simulate", str(GOLDEN / "rc.cir"), "--engine", "ngspice", "--csv", str(out)]) == 0
    assert Waveforms.from_csv(out)["v(out)"].size > 100


def _loaded_after(code: str, packages: tuple[str, ...]) -> list[str]:
    """The modules of ``packages`` (names, and their submodules) that a fresh interpreter
    has imported after running ``code``."""
    import json
    import subprocess
    import sys

    script = (
        f"import json, sys\n{code}\n"
        f"packages = {list(packages)!r}\n"
        "print(json.dumps(sorted(m for m in sys.modules\n"
        "                        if any(m == p or m.startswith(p + '.') for p in packages))))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_simulate_loads_no_comparison_or_sweep_code(tmp_path):
    """A one-netlist run pays for what it uses: the sweep and comparison modules (with
    scipy.interpolate and scipy.signal, about half a second to import), the translator and
    the ODE side (scipy.optimize, scipy.integrate), plotting and graphs stay unloaded."""
    netlist = tmp_path / "rc.cir"
    netlist.write_text("* rc\nV1 a 0 DC 1\nR1 a b 1k\nC1 b 0 1u\n.tran 10u 1m\n.end\n")
    code = f"from circuitsim.cli import main\nassert main(['simulate', {str(netlist)!r}]) == 0"
    unused = ("circuitsim.compare.sweep", "circuitsim.compare.comparison", "scipy.interpolate",
              "scipy.signal", "scipy.optimize", "scipy.integrate", "matplotlib", "networkx",
              "circuitsim.synthesis", "circuitsim.mechanics", "circuitsim.interop",
              "circuitsim.studies")  # fmt: skip
    assert _loaded_after(code, unused) == []


def test_command_line_parser_loads_no_numerics():
    """Building the command line (every verb's options) imports no numpy, scipy, numba,
    matplotlib or networkx, and none of the translator, ODE or engine side: a verb loads what
    it runs. (The bench verb's --overload default once imported the translator, and with it
    scipy.optimize and scipy.integrate, into every process; the sweep verb's help, naming
    compare.values' limit, imported numpy: docs/performance.md section 6.)"""
    code = "from circuitsim.cli import build_parser\nbuild_parser()"
    heavy = ("numpy", "scipy", "numba", "matplotlib", "networkx", "circuitsim.synthesis",
             "circuitsim.mechanics", "circuitsim.solver", "circuitsim.interop",
             "circuitsim.studies", "circuitsim.bench")  # fmt: skip
    assert _loaded_after(code, heavy) == []


def test_process_entry_point_freezes_the_collector_before_exit(tmp_path):
    """``python -m circuitsim`` and the ``circuitsim`` script end through ``cli.run``, which
    moves every object to the collector's permanent generation before the interpreter shuts
    down (its collections over numba's and scipy's objects were 0.4 s of a 2 s process:
    docs/performance.md section 6), and exits with main's code."""
    import json
    import subprocess
    import sys
    import tomllib

    netlist = tmp_path / "rc.cir"
    netlist.write_text("* rc\nV1 a 0 DC 1\nR1 a b 1k\nC1 b 0 1u\n.tran 10u 1m\n.end\n")
    script = (
        "import gc, json, runpy, sys\n"
        f"sys.argv = ['circuitsim', 'simulate', {str(netlist)!r}]\n"
        "try:\n"
        "    runpy.run_module('circuitsim', run_name='__main__')\n"
        "except SystemExit as exc:\n"
        "    print(json.dumps([exc.code, gc.get_freeze_count()]))\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    code, frozen = json.loads(done.stdout.strip().splitlines()[-1])
    assert code == 0 and frozen > 10_000  # the loaded modules' objects, numpy's and ours
    project = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    assert project["project"]["scripts"]["circuitsim"] == "circuitsim.cli:run"


@pytest.mark.parametrize("setting, expected", [(None, 1), ("2", 2)])
def test_process_entry_point_starts_openblas_on_one_thread(tmp_path, setting, expected):
    """``cli.run`` starts every OpenBLAS of the process (numpy's, scipy's) on one thread, so
    that no pool of idle threads spins beside the run (0.2 s of CPU in a wheelset process:
    docs/performance.md section 6); a user's OPENBLAS_NUM_THREADS is kept."""
    import json
    import os
    import subprocess
    import sys

    if setting is None and (os.cpu_count() or 1) < 2:
        pytest.skip("one CPU: OpenBLAS starts one thread whatever the entry point does")
    netlist = tmp_path / "rc.cir"
    netlist.write_text("* rc\nV1 a 0 DC 1\nR1 a b 1k\nC1 b 0 1u\n.tran 10u 1m\n.end\n")
    script = (
        "import json, runpy, sys\n"
        f"sys.argv = ['circuitsim', 'simulate', {str(netlist)!r}]\n"
        "try:\n"
        "    runpy.run_module('circuitsim', run_name='__main__')\n"
        "except SystemExit:\n"
        "    import scipy.linalg\n"
        "    from circuitsim.solver.threads import _scan\n"
        "    print(json.dumps([get() for get, _ in _scan()]))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if setting is not None:
        env["OPENBLAS_NUM_THREADS"] = setting
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env=env)  # fmt: skip
    assert done.returncode == 0, done.stderr
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(counts) >= 1 and set(counts) == {expected}


def test_summary_names_the_kernel_and_why_the_python_loop_ran(tmp_path, capsys):
    from circuitsim.cli import main

    netlist = tmp_path / "r.cir"
    netlist.write_text("* r\nV1 a 0 DC 1\nR1 a 0 1k\n.tran 1u 10u\n.end\n")
    assert main(["simulate", str(netlist)]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith(
        f"{netlist}: builtin (python kernel: no charges, junctions or switches (nothing for the "
        "kernel to integrate)), "
    )
    assert main(["simulate", str(GOLDEN / "rc.cir")]) == 0
    assert "builtin (ports kernel), " in capsys.readouterr().out


def test_engine_errors_name_the_netlist(tmp_path, capsys):
    from circuitsim.cli import main

    netlist = tmp_path / "d.cir"
    netlist.write_text("* d\nV1 a 0 DC 1\nD1 a 0 nom\n.op\n.end\n")
    assert main(["simulate", str(netlist)]) == 2
    assert f"error: {netlist}: D1: no .model 'nom'" in capsys.readouterr().err


RECTIFIER_WITHOUT_KERNEL = """* a diode the compiled kernels cannot run: bypass has no compiled form
V1 in 0 SIN(0 1 1k)
R1 in a 1k
D1 a b DX
C1 b 0 1u
.model DX D(is=1e-14)
.options bypass=1
.tran 10u 1m
.end
"""


def test_a_fallback_to_the_numpy_loop_is_said_on_stderr_and_in_the_summary(
    tmp_path, capsys, monkeypatch
):
    # each way the default kernel ("auto") can end on the numpy reference loop, slower: a
    # device without a compiled model, and numba missing
    import sys

    netlist = tmp_path / "rectifier.cir"
    netlist.write_text(RECTIFIER_WITHOUT_KERNEL)
    assert main(["simulate", str(netlist)]) == 0
    captured = capsys.readouterr()
    reason = "no compiled model for DiodeFamily"
    assert f"warning: the compiled kernels cannot run this circuit ({reason})" in captured.err
    assert f": builtin (python kernel: {reason}), " in captured.out.splitlines()[0]

    monkeypatch.setitem(sys.modules, "numba", None)  # `import numba` raises ImportError
    assert main(["simulate", str(GOLDEN / "rc.cir")]) == 0
    captured = capsys.readouterr()
    reason = "numba is not installed"
    assert f"warning: the compiled kernels cannot run this circuit ({reason})" in captured.err
    assert f": builtin (python kernel: {reason}), " in captured.out.splitlines()[0]
