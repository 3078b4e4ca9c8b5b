"""``.include parts.lib`` (the package part library) runs in ngspice as it does in our engine.

The reader's documented fallback (docs/netlists.md): an include file not found beside the
netlist is looked for in ``circuitsim/netlist/library``. ngspice knows only the first place,
so the runner must point it at the library. The expected answer is the inverting amplifier's
closed-loop gain with the library op-amp's finite open-loop gain A (OPAMP_IDEAL, A = 1e6):
v(out) = -(R2/R1) vin / (1 + (1 + R2/R1) / A).
"""

from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.netlist.reader import read_netlist
from tests.conftest import requires_ngspice

pytestmark = [requires_ngspice, pytest.mark.ngspice]

AMPLIFIER = (
    "* uses the package part library\n"
    ".include parts.lib\n"
    "V1 in 0 DC 1\n"
    "R1 in m 10k\n"
    "R2 m out 20k\n"
    "X1 0 m out OPAMP_IDEAL\n"
    ".op\n"
    ".end\n"
)


def _closed_loop(gain: float) -> float:
    return -2.0 / (1.0 + 3.0 / gain)


def _write(folder: Path) -> Path:
    path = folder / "libuse.cir"
    path.write_text(AMPLIFIER)
    return path


def test_package_library_include_runs_in_ngspice(tmp_path):
    path = _write(tmp_path)
    assert not (tmp_path / "parts.lib").exists()
    out = run_ngspice(path)["v(out)"][0]
    assert out == pytest.approx(_closed_loop(1e6), rel=1e-9)


def test_cli_simulate_with_ngspice_and_builtin_agree(tmp_path, capsys):
    path = _write(tmp_path)
    assert main(["simulate", str(path), "--engine", "ngspice"]) == 0
    ngspice_out = capsys.readouterr().out
    assert main(["simulate", str(path)]) == 0
    builtin_out = capsys.readouterr().out
    for printed in (ngspice_out, builtin_out):
        assert "v(out) = -1.99999" in printed


def test_a_file_beside_the_netlist_wins_as_in_the_reader(tmp_path):
    # the local parts.lib defines OPAMP_IDEAL with an open-loop gain of 10
    (tmp_path / "parts.lib").write_text(
        "* local parts\n.subckt OPAMP_IDEAL inp inm out\nEOUT out 0 inp inm 10\n.ends\n"
    )
    path = _write(tmp_path)
    assert run_ngspice(path)["v(out)"][0] == pytest.approx(_closed_loop(10.0), rel=1e-9)
    from circuitsim.solver import simulate

    builtin = simulate(read_netlist(path))["v(out)"][0]
    assert builtin == pytest.approx(_closed_loop(10.0), rel=1e-9)


def test_library_include_in_netlist_text(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no parts.lib in the working directory either
    assert run_ngspice(AMPLIFIER)["v(out)"][0] == pytest.approx(_closed_loop(1e6), rel=1e-9)


def test_quoted_include_name(tmp_path):
    text = AMPLIFIER.replace(".include parts.lib", ".include 'parts.lib'")
    path = tmp_path / "quoted.cir"
    path.write_text(text)
    assert run_ngspice(path)["v(out)"][0] == pytest.approx(_closed_loop(1e6), rel=1e-9)
