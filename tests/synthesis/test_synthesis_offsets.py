"""Op-amp input offset voltage and bias currents: set per section, the same in both engines,
their equilibrium shift against the hand value, and generate's warning."""

import shutil
from pathlib import Path

import numpy as np
import pytest

from circuitsim.compare.case import run_case
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.mechanics import load_model
from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import simulate
from circuitsim.studies.reproduce import Scenario
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.offsets import (
    apply_opamp_errors,
    offset_shift,
    offset_warning,
    opamp_sections,
)
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)
LEAK_MODEL = Path(__file__).resolve().parents[1] / "studies" / "leak.toml"

# a follower whose in+ sees 1 GOhm to ground, and an inverter of gain -1 with in+ grounded
BENCH = """input errors of the TL074 model
.include parts.lib
VCC vcc 0 15
VEE vee 0 -15
RS in 0 1G
X1 in out vcc vee out TL074 vos=3m ib=30p ios=5p
R2 0 a 10k
X2 0 a vcc vee b TL074 vos=-2m ib=1n
R3 a b 10k
.tran 1u 20u
.end
"""


@pytest.fixture(scope="module")
def wheelset():
    return Scenario(3.0, True).system(load_model())


def _bench_expected():
    # follower: in = -(ib + ios/2) * 1 GOhm, out = in + vos
    follower = -(30e-12 + 2.5e-12) * 1e9 + 3e-3
    # inverter with in+ at vos: a = vos, the 1 nA drawn from a flows through R3 from b
    inverter = 2 * -2e-3 + 1e-9 * 10e3
    return follower, inverter


def test_offset_and_bias_currents_give_the_hand_values_in_our_engine():
    waves = simulate(parse_netlist(BENCH))
    follower, inverter = _bench_expected()
    assert waves["v(out)"][-1] == pytest.approx(follower, rel=1e-4)
    assert waves["v(b)"][-1] == pytest.approx(inverter, rel=1e-4)


@requires_ngspice
@pytest.mark.ngspice
def test_offset_and_bias_currents_give_the_hand_values_in_ngspice(tmp_path):
    from circuitsim.netlist.library import LIBRARY_PATH

    (tmp_path / "parts.lib").write_text(LIBRARY_PATH.read_text())
    path = tmp_path / "bench.cir"
    path.write_text(BENCH)
    waves = run_ngspice(path)
    follower, inverter = _bench_expected()
    assert waves["v(out)"][-1] == pytest.approx(follower, rel=1e-4)
    assert waves["v(b)"][-1] == pytest.approx(inverter, rel=1e-4)


def test_offsets_are_set_per_section_with_a_default(wheelset):
    options = SynthesisOptions(
        opamp="tl074", series="exact", opamp_offset={"*": 1e-3, "u1a": -3e-3},
        opamp_bias={"XU2D": 30e-12},
    )  # fmt: skip
    sections = opamp_sections(synthesize(wheelset, options).circuit)
    assert sections["U1A"].params["vos"] == -3e-3
    assert all(c.params["vos"] == 1e-3 for name, c in sections.items() if name != "U1A")
    assert sections["U2D"].params["ib"] == 30e-12
    assert "ib" not in sections["U1A"].params
    # no option: the calls carry no parameter, the library's 0 applies (results unchanged)
    plain = opamp_sections(synthesize(wheelset, SynthesisOptions(opamp="tl074")).circuit)
    assert all(not c.params for c in plain.values())


def test_bad_offsets_are_refused_with_the_reason(wheelset):
    circuit = synthesize(wheelset, SynthesisOptions(opamp="tl074", series="exact")).circuit
    with pytest.raises(SynthesisError, match="U9Z: no such op-amp section .*U1A"):
        apply_opamp_errors(circuit, {"U9Z": 1e-3})
    with pytest.raises(SynthesisError, match="finite"):
        apply_opamp_errors(circuit, {"U1A": float("nan")})
    with pytest.raises(SynthesisError, match="tl074"):
        SynthesisOptions(opamp_offset={"*": 3e-3}).validated()
    ideal = synthesize(wheelset, SynthesisOptions(series="exact")).circuit
    with pytest.raises(SynthesisError, match="ideal op-amp has no input errors"):
        apply_opamp_errors(ideal, {"U1A": 1e-3})


@pytest.mark.parametrize("scaling", ["unity", "auto"])
def test_an_integrators_offset_shifts_its_state_by_the_offset_over_the_scale(scaling):
    """dx/dt = -x/tau with no other input: at DC the integrator's junction sits at vos and
    its one input resistor carries no current, so its output (the state's negative node) is
    at vos; the inverter (in+ at vos too) puts -(v_minus - vos) + vos = vos on the state
    node: x shifts by vos / G."""
    system = load_model(LEAK_MODEL).system()
    options = SynthesisOptions(scaling=scaling, series="exact", ranges={"x": 0.25})
    synthesis = synthesize(system, options)
    assert synthesis.scale_map.states["x"].volts_per_unit == (1.0 if scaling == "unity" else 20)
    G = synthesis.scale_map.states["x"].volts_per_unit
    shift = offset_shift(synthesis.circuit, synthesis.scale_map, 3e-3)
    assert shift.volts["x"] == pytest.approx(3e-3, rel=1e-4)  # the op-amps' gain: 1e6
    assert shift.shift["x"] == pytest.approx(3e-3 / G, rel=1e-4)


def test_generate_warns_of_offsets_at_unity_scaling_only(wheelset):
    unity = synthesize(wheelset, SynthesisOptions(scaling="unity"))
    warning = offset_warning(unity, wheelset)
    assert warning is not None
    # the flange term's kinks at eta = 9 mm are 9 mV at 1 V/m: 3 mV is a third of it
    assert "flange term's kinks (at 9 mV) by 33.3 %" in warning
    assert "y's equilibrium" in warning
    auto = synthesize(wheelset, SynthesisOptions(scaling="auto"))
    assert offset_warning(auto, wheelset) is None


@requires_ngspice
@pytest.mark.ngspice
def test_unity_scaling_with_offsets_is_the_same_in_both_engines(wheelset, tmp_path):
    """The issue's case: 3 mV on every TL074 section at the paper's unity scaling. Both
    engines see the same large error against the ODE, and their traces agree."""
    options = SynthesisOptions(
        opamp="tl074", scaling="unity", series="exact",
        opamp_offset={"*": 3e-3, "U2C": -2e-3}, opamp_bias={"*": 30e-12},
    )  # fmt: skip
    ours = run_case(wheelset, options, "builtin")
    theirs = run_case(wheelset, options, "ngspice", netlist=tmp_path / "offsets.cir")
    y_ours = ours.comparison.states["y"].nrmsd_percent
    y_theirs = theirs.comparison.states["y"].nrmsd_percent
    assert y_ours > 5.0  # 0.04 % without offsets (measured); the offsets dominate
    assert y_ours == pytest.approx(y_theirs, rel=0.02)
    t, ref = ours.circuit["y"]
    other = np.interp(t, *theirs.circuit["y"])
    assert nrmsd_percent(ref, other) < 0.2
    # and the offsets are in the file ngspice ran
    text = (tmp_path / "offsets.cir").read_text()
    assert "XU2C" in text and "vos=-2m" in text.replace("-0.002", "-2m")


def test_generate_writes_the_offsets_per_section(tmp_path):
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    path = tmp_path / "w.cir"
    done = subprocess.run(
        [sys.executable, "-m", "circuitsim", "generate", "--opamp", "tl074", "--opamp-offset",
         "3m", "--opamp-offset", "U1A=-1m", "--opamp-bias", "30p", "-o", str(path)],
        capture_output=True, text=True, cwd=root, timeout=300,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = {line.split()[0]: line for line in path.read_text().splitlines() if line[:1] == "X"}
    assert lines["XU1A"].endswith("TL074 vos=-1m ib=30p")
    assert lines["XU2D"].endswith("TL074 vos=3m ib=30p")
    refused = subprocess.run(
        [sys.executable, "-m", "circuitsim", "generate", "--opamp-offset", "3m", "-o",
         str(tmp_path / "x.cir")],
        capture_output=True, text=True, cwd=root, timeout=300,
    )  # fmt: skip
    assert refused.returncode == 2
    assert "--opamp-offset needs --opamp tl074" in refused.stderr
    assert not (tmp_path / "x.cir").exists()
