"""Vendor-macromodel devices (POLY E/G/F/H, JFET, BJT) against ngspice and closed forms.

Golden netlists in golden_vendor/ run in both engines: the transient point by point (ours
interpolated onto ngspice's times, deviation relative to each signal's range in ngspice's
run) and the operating point (absolute difference relative to the largest node voltage).
The limit is the issue's: 1e-3 of range.
"""

import warnings
from pathlib import Path

import numpy as np
import pytest

from circuitsim.netlist.reader import parse_netlist, read_netlist
from circuitsim.netlist.writer import write_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.devices.poly import exponents
from circuitsim.solver.engine import operating_point
from circuitsim.solver.errors import CircuitInputError, KernelFallbackWarning
from tests.solver.conftest import requires_ngspice
from tests.solver.test_golden import deviations

GOLDEN = Path(__file__).parent / "golden_vendor"
NETLISTS = ["poly_e.cir", "poly_g.cir", "poly_f.cir", "poly_h.cir", "jfet.cir", "bjt.cir"]
LIMIT = 1e-3


def test_every_vendor_golden_netlist_is_tested():
    assert sorted(p.name for p in GOLDEN.glob("*.cir")) == sorted(NETLISTS)


@requires_ngspice
@pytest.mark.parametrize("kernel", ["python", "compiled"])
@pytest.mark.parametrize("name", NETLISTS)
def test_transient_against_ngspice(name, kernel):
    from circuitsim.interop.ngspice import run_ngspice

    path = GOLDEN / name
    circuit = read_netlist(path)
    ours = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    assert ours.stats["kernel"] == kernel
    reference = run_ngspice(path)
    devs = deviations(ours, reference, "all")
    missing = [n for n in reference.names if n.startswith("v(") and n not in ours.signals]
    assert devs and not missing
    worst = max(devs, key=devs.get)
    assert devs[worst] <= LIMIT, f"{name}: {worst} deviates {devs[worst]:.3g} of its range"


@requires_ngspice
@pytest.mark.parametrize("name", NETLISTS)
def test_operating_point_against_ngspice(name):
    from circuitsim.interop.ngspice import run_ngspice

    path = GOLDEN / name
    ours = operating_point(read_netlist(path))
    reference = run_ngspice(path, analysis="op")
    nodes = [n for n in reference.names if n.startswith("v(")]
    scale = max(abs(reference[n][0]) for n in nodes)
    worst = max(nodes, key=lambda n: abs(ours[n][0] - reference[n][0]))
    error = abs(ours[worst][0] - reference[worst][0]) / scale
    assert error <= LIMIT * 1e-2, f"{name}: {worst} differs by {error:.3g} of the largest node"


# --- POLY: SPICE 2G6's term order and the polynomial's value ------------------------------


def test_poly_term_order_is_spice2g6():
    # 2-D: p0, a, b, a^2, ab, b^2, a^3, a^2 b, a b^2, b^3
    assert exponents(2, 10).tolist() == [
        [0, 0], [1, 0], [0, 1], [2, 0], [1, 1], [0, 2], [3, 0], [2, 1], [1, 2], [0, 3],
    ]  # fmt: skip
    # 3-D second order: a^2, ab, ac, b^2, bc, c^2 after the linear terms
    assert exponents(3, 10)[4:].tolist() == [
        [2, 0, 0], [1, 1, 0], [1, 0, 1], [0, 2, 0], [0, 1, 1], [0, 0, 2],
    ]  # fmt: skip


def test_poly_vcvs_operating_point_is_the_polynomial():
    circuit = parse_netlist(
        "* poly\nVA a 0 0.7\nVB b 0 -1.3\nVC c 0 0.4\n"
        "E1 out 0 POLY(3) a 0 b 0 c 0 0.5 1 2 3 0.1 0.2 0.3 0.4 0.5 0.6 0.05\n"
        "RL out 0 1k\n.op\n.end\n"
    )
    a, b, c = 0.7, -1.3, 0.4
    expected = (
        0.5 + a + 2 * b + 3 * c
        + 0.1 * a * a + 0.2 * a * b + 0.3 * a * c + 0.4 * b * b + 0.5 * b * c + 0.6 * c * c
        + 0.05 * a**3
    )  # fmt: skip
    assert operating_point(circuit)["v(out)"][0] == pytest.approx(expected, rel=1e-12)


def test_poly_one_coefficient_is_the_constant_as_ngspice():
    circuit = parse_netlist("* k\nVA a 0 3\nE1 out 0 POLY(1) a 0 2.5\nRL out 0 1k\n.end\n")
    assert operating_point(circuit)["v(out)"][0] == pytest.approx(2.5)


def test_linear_poly_runs_on_the_compiled_kernel():
    """Degree-1 POLY without a constant is a linear stamp: no fallback to the numpy loop."""
    text = (
        "* linear poly summer\nVA a 0 SIN(0 1 1k)\nVB b 0 SIN(0 0.5 3k)\nRA a 0 1k\nRB b 0 1k\n"
        "E1 s 0 POLY(2) a 0 b 0 0 2 -1\nR1 s i 10k\nC1 i 0 10n\n.tran 10u 2m\n.end\n"
    )
    circuit = parse_netlist(text)
    ours = simulate(circuit)
    reference = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="python"))
    assert not ours.stats["kernel"].startswith("python")
    assert np.allclose(np.interp(reference.time, ours.time, ours["v(i)"]), reference["v(i)"],
                       atol=1e-4)  # fmt: skip


@pytest.mark.parametrize("device", ["jfet.cir", "bjt.cir", "poly_g.cir"])
def test_auto_runs_transistors_and_poly_on_the_mna_kernel_and_ports_refuses(device):
    """kernel=auto: the MNA kernel, without a fallback warning; the ports kernel has no
    multi-terminal devices and says so, naming the family."""
    circuit = read_netlist(GOLDEN / device)
    family = {"jfet.cir": "JfetFamily", "bjt.cir": "BjtFamily", "poly_g.cir": "PolyVccsFamily"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", KernelFallbackWarning)
        waves = simulate(circuit, SimulationOptions.from_circuit(circuit, max_steps=50_000))
    assert waves.stats["kernel"] == "compiled"
    with pytest.raises(
        CircuitInputError, match=f"kernel=ports: no compiled model for {family[device]} in the"
    ):
        simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))


# --- reading, writing, refusing ---------------------------------------------------------


@pytest.mark.parametrize("name", NETLISTS)
def test_round_trip_keeps_every_vendor_element(name):
    circuit = read_netlist(GOLDEN / name)
    again = parse_netlist(write_netlist(circuit))
    assert again.elements == circuit.elements
    assert again.models == circuit.models


def test_unmodelled_bjt_parameter_is_refused_by_name():
    circuit = parse_netlist(
        "* q\nVC c 0 5\nVB b 0 0.7\nQ1 c b 0 qx\n.model qx NPN(BF=50 PTF=20)\n.op\n.end\n"
    )
    with pytest.raises(CircuitInputError, match=r"Q1 \(.model qx\): PTF=20.*not supported"):
        operating_point(circuit)


def test_wrong_model_kind_names_the_transistor():
    circuit = parse_netlist("* j\nVD d 0 5\nJ1 d 0 0 qx\n.model qx NPN(BF=50)\n.op\n.end\n")
    with pytest.raises(CircuitInputError, match="J1: .model qx is not NJF or PJF"):
        operating_point(circuit)


def test_poly_reader_errors_name_the_line():
    from circuitsim.netlist.errors import NetlistError

    with pytest.raises(NetlistError, match=r":2: .*POLY needs at least one coefficient"):
        parse_netlist("* p\nE1 o 0 POLY(1) a 0\nR1 o 0 1\nR2 a 0 1\n.end\n")
    with pytest.raises(NetlistError, match=r":2: .*POLY dimension must be a whole number"):
        parse_netlist("* p\nG1 o 0 POLY(x) a 0 1\n.end\n")
