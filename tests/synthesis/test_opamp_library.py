"""``generate --opamp-lib FILE --opamp-subckt NAME``: a user's 5-pin op-amp subcircuit.

Loading is checked (file, subcircuit, five pins, a unit-gain follower that follows); the
generated circuit carries the subcircuit, passes the mapping check, and lists the sections
in the BOM. The wheelset with the two Boyle macromodels of netlist/library/macromodels.lib
(JFET input with POLY sources; bipolar input) runs in the builtin engine within 1e-3 of
ngspice's node-voltage ranges and within 2 % NRMSD of the ODE, on the compiled MNA kernel
(slow: ngspice's run and the kernel's first compile).
"""

import shutil
from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.mechanics import load_model, solve
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.opamp_library import load_opamp
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap
from tests.solver.test_golden import deviations

MACROMODELS = Path(__import__("circuitsim").__file__).parent / "netlist/library/macromodels.lib"
requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def _lib(tmp_path, text: str) -> Path:
    path = tmp_path / "user.lib"
    path.write_text(f"* a user's library\n.include {MACROMODELS}\n{text}")
    return path


@pytest.mark.parametrize("name", ["BOYLE_TL07X", "boyle_ua741"])
def test_the_shipped_macromodels_load_and_follow(name):
    opamp = load_opamp(MACROMODELS, name)
    assert opamp.name.lower() == name.lower() and len(opamp.subcircuit.ports) == 5


def test_missing_file_and_subcircuit_are_named(tmp_path):
    with pytest.raises(SynthesisError, match=r"nope.lib: no such file"):
        load_opamp(tmp_path / "nope.lib", "X")
    with pytest.raises(SynthesisError, match=r"no subcircuit 'LM358'.*BOYLE_TL07X, BOYLE_UA741"):
        load_opamp(MACROMODELS, "LM358")


def test_a_subcircuit_without_five_pins_is_refused(tmp_path):
    path = _lib(tmp_path, ".subckt FOUR a b c d\nR1 a b 1k\nR2 c d 1k\n.ends\n")
    with pytest.raises(SynthesisError, match=r"user.lib: subcircuit FOUR has 4 pins .*needs 5"):
        load_opamp(path, "four")


def test_swapped_inputs_fail_the_open_loop_check(tmp_path):
    path = _lib(tmp_path, ".subckt SWAPPED a b c d e\nX1 b a c d e BOYLE_TL07X\n.ends\n")
    expected = r"SWAPPED: open loop with in\+ - in- = -0.1 V its output is 13.5.*pins in the order"
    with pytest.raises(SynthesisError, match=expected):
        load_opamp(path, "SWAPPED")


def test_an_undefined_model_is_named(tmp_path):
    path = _lib(tmp_path, ".subckt BAD p m vp vn o\nQ1 o p m qnone\nR1 o vn 1k\n.ends\n")
    with pytest.raises(SynthesisError, match=r"subcircuit BAD: Q1 uses model 'qnone'"):
        load_opamp(path, "BAD")


def test_generated_circuit_carries_the_library_opamp(tmp_path):
    system = load_model().system(parameters={"V": 55.0, "f": 3.0})
    options = SynthesisOptions(
        opamp="lib", opamp_lib=str(MACROMODELS), opamp_subckt="BOYLE_TL07X", series="exact"
    )
    result = generate(system, tmp_path / "w.cir", options)
    assert result.report.ok
    circuit = read_netlist(result.netlist)
    calls = [e for e in circuit.elements if e.name.upper().startswith("X")]
    assert len(calls) == 13 and all(c.subcircuit.upper() == "BOYLE_TL07X" for c in calls)
    assert all(c.connections[2:4] == ("vcc", "vee") for c in calls)
    bom = result.bom_file.read_text()
    assert bom.count("BOYLE_TL07X") >= 1


def test_cli_refuses_half_or_two_opamp_choices(tmp_path, capsys):
    out = str(tmp_path / "w.cir")
    assert main(["generate", "--opamp-lib", str(MACROMODELS), "-o", out]) == 2
    assert "--opamp-lib FILE and --opamp-subckt NAME go together" in capsys.readouterr().err
    args = ["--opamp", "tl074", "--opamp-lib", str(MACROMODELS), "--opamp-subckt", "BOYLE_TL07X"]
    assert main(["generate", *args, "-o", out]) == 2
    assert "choose one op-amp model" in capsys.readouterr().err
    assert main(["generate", "--opamp-lib", str(tmp_path / "no.lib"), "--opamp-subckt", "A",
                 "-o", out]) == 2  # fmt: skip
    assert "no.lib: no such file" in capsys.readouterr().err


# --- the wheelset with each macromodel: builtin engine vs ngspice vs the ODE ---------------


@pytest.mark.slow
@requires_ngspice
@pytest.mark.parametrize("subckt", ["BOYLE_TL07X", "BOYLE_UA741"])
def test_wheelset_with_macromodel_matches_ngspice_and_the_ode(tmp_path, subckt):
    from circuitsim.interop.ngspice import run_ngspice
    from circuitsim.solver import SimulationOptions, simulate

    system = load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.040})
    options = SynthesisOptions(
        opamp="lib", opamp_lib=str(MACROMODELS), opamp_subckt=subckt, series="exact", t_stop=2.0
    )
    result = generate(system, tmp_path / "w.cir", options)
    assert result.report.ok
    circuit = read_netlist(result.netlist)
    # at shared-machine load: no wall-time limit (a cold kernel compiles for minutes)
    options = SimulationOptions.from_circuit(circuit, max_wall_time=None)
    ours = simulate(circuit, options)
    assert ours.stats["kernel"] == "compiled"
    reference = run_ngspice(result.netlist)
    # the state nodes (each state and its negative): what the circuit computes. Inside the
    # |x| blocks the op-amps run open loop through each zero crossing and start up from the
    # uic state in microseconds; there a point-by-point comparison measures where each
    # engine put its time steps on a glitch (measured: the flange signal 3.4e-3 of its
    # range at a crossing, an |x| summing node 1.0 in the first microseconds)
    scale = ScaleMap.load(result.scale_file)
    states = {s.node for s in scale.states.values()}
    states |= {f"{node}_neg" for node in states}
    devs = {n: d for n, d in deviations(ours, reference, "voltages").items() if n[2:-1] in states}
    assert len(devs) == 8
    worst = max(devs, key=devs.get)
    assert devs[worst] <= 1e-3, f"{subckt}: {worst} deviates {devs[worst]:.3g} of its range"
    ode = solve(system, (0.0, result.synthesis.t_stop))
    for waves in (ours, reference):
        for state, (t, values) in map_waveforms(waves, scale, ["y", "y_dot"]).items():
            error = nrmsd_percent(ode.sol(t)[system.states.index(state)], values)
            assert error <= 2.0, f"{subckt} {waves.engine}: {state} NRMSD {error:.3f} %"
