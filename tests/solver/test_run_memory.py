"""The memory budget measured: a process's peak resident memory stays within its budget.

Each case runs ``circuitsim simulate`` in a child process and reads the child's peak resident
memory from ``os.wait4`` (the kernel's own count, ngspice's included when it runs under it).
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import requires_ngspice
from tests.solver.test_run_guards import ladder

ROOT = Path(__file__).resolve().parents[2]
TL074_WHEELSET = ROOT / "netlists" / "wheelset_flange_tl074_ngspice.cir"
MB = 1e6


# A small process starts the measured one and reports its peak: Linux hands a child the
# resident high-water mark of the process that forked it (the test runner: a gigabyte in a
# whole-suite run), so the runner itself must not be that parent.
LAUNCHER = """
import os, subprocess, sys
with open(sys.argv[1], "wb") as err:
    child = subprocess.Popen(sys.argv[2:], stdout=subprocess.DEVNULL, stderr=err)
    _, status, usage = os.wait4(child.pid, 0)
print(usage.ru_maxrss)
sys.exit(os.waitstatus_to_exitcode(status))
"""


def peak_run(args: list[str], folder: Path) -> tuple[int, float, str]:
    """(exit code, peak resident memory in bytes, stderr) of ``python -m circuitsim ARGS``."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    err = folder / "stderr.txt"
    done = subprocess.run(
        [sys.executable, "-c", LAUNCHER, str(err), sys.executable, "-m", "circuitsim", *args],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
    )
    return done.returncode, float(done.stdout.strip()) * 1024.0, err.read_text()


@pytest.fixture(autouse=True, scope="module")
def kernels_ready():
    """The kernels compiled before any measured run: a child that compiles them (a cold
    cache) peaks at its compiler's memory, not its run's."""
    from circuitsim.solver.compiled import warm_up

    warm_up(("ports", "compiled"))


def fine_wheelset(folder: Path, tran: str) -> Path:
    """The TL074 wheelset with its ``.tran`` replaced."""
    text = TL074_WHEELSET.read_text()
    lines = [tran if line.lower().startswith(".tran") else line for line in text.splitlines()]
    path = folder / "fine.cir"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow
def test_fine_tl074_wheelset_is_refused_at_once(tmp_path):
    # the case: 20 s in steps of 1 us (it grew to 3.7 GB before the step limit)
    netlist = fine_wheelset(tmp_path, ".tran 1u 20 0 1u uic")
    code, peak, err = peak_run(["simulate", str(netlist), "--csv", "x.csv"], tmp_path)
    assert code == 3 and "at least 2e+07 time steps" in err and "limit of 2,000,000" in err
    # past the step limit, its memory: 2e7 points of 246 signals, 39.5 GB
    budget = 300 * MB
    code, peak, err = peak_run(
        ["simulate", str(netlist), "--max-steps", "30000000", "--max-memory", "300M"], tmp_path
    )
    assert code == 3 and "above the memory budget of 300 MB" in err
    assert "39.5 GB" in err
    assert peak < budget
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.slow
def test_recording_stops_within_its_budget(tmp_path):
    # 100 nodes at about 9,000 points per model second: 20 s would record about 150 MB; the
    # estimate from TMAX (2,001 points, 1.6 MB) passes, the recorder stops the run
    netlist = tmp_path / "long.cir"
    netlist.write_text(ladder(100, ".tran 10m 20"))

    def run(budget: str) -> float:
        args = ["simulate", str(netlist), "--kernel", "compiled", "--max-memory", budget]
        code, peak, err = peak_run(args, tmp_path)
        assert code == 3 and f"the memory budget is {budget[:-1]} MB" in err, err
        return peak

    # the same run stopped at 2 MB: the process's memory without the recorded table (the
    # error's path imports modules a finished run does not, about 50 MB)
    baseline = run("2M")
    assert run("30M") - baseline < 30 * MB
    # and the measure sees a table: a 100 MB budget lets it reach 54 MB (the next doubling
    # would pass the budget)
    assert 30 * MB < run("100M") - baseline < 100 * MB


@requires_ngspice
@pytest.mark.slow
def test_ngspice_is_stopped_within_its_budget(tmp_path):
    # ngspice keeps 22 signals at each of at least 1e6 points (184 MB) and grows its vectors
    # by reallocation; a 250 MB budget passes the estimate and stops ngspice while it runs
    netlist = tmp_path / "ladder.cir"
    netlist.write_text(ladder(20, ".tran 1u 1"))
    code, peak, err = peak_run(
        ["simulate", str(netlist), "--engine", "ngspice", "--max-memory", "250M"], tmp_path
    )
    assert code == 3 and "the memory budget is 250 MB" in err, err
    # ngspice's address space is capped at its size at the start (about 200 MB, mostly
    # libraries and reserved heap) plus the budget (ngspice_limits.RunWatch)
    assert peak < 250 * MB + 250 * MB


@pytest.mark.slow
def test_large_tl074_chain_with_a_fine_step_is_refused_at_once(tmp_path):
    # the 64-mass TL074 chain (benchmarks/bench_scaling.py's largest): the step limit
    # allows 2e6 steps, which at every signal would record about 166 GB
    import re

    from circuitsim.mechanics import load_model
    from circuitsim.mechanics.chain import chain_model_text
    from circuitsim.synthesis.generate import generate
    from circuitsim.synthesis.options import SynthesisOptions

    model_file = tmp_path / "chain64.toml"
    model_file.write_text(chain_model_text(64, 5.0))
    model = load_model(model_file)
    system = model.system(nonlinear={group: True for group in model.nonlinear_terms})
    netlist = tmp_path / "chain64.cir"
    generate(system, netlist, SynthesisOptions(opamp="tl074", series="exact", t_stop=5.0))
    lines = netlist.read_text().splitlines()
    lines = [".tran 1u 2 0 1u uic" if ln.lower().startswith(".tran") else ln for ln in lines]
    netlist.write_text("\n".join(lines) + "\n")
    code, peak, err = peak_run(["simulate", str(netlist), "--max-memory", "4G"], tmp_path)
    assert code == 3 and "above the memory budget of 4 GB" in err, err
    found = re.search(r"need at least ([\d.]+) GB \(2e\+06 time points x (\d+) signals", err)
    signals = int(found[2])
    assert signals > 10_000  # 64 masses of TL074 blocks
    assert float(found[1]) == pytest.approx((2e6 + 1) * (signals + 1) * 8 / 1e9, rel=1e-2)
    assert peak < 4 * 1e9  # refused before any of it is recorded
