"""JFETs, BJTs and nonlinear POLY sources on the compiled MNA kernel (compiled/mna_terminals.py
and the families' kernel twins) against the numpy reference loop, which is their
specification: the same steps within round-off, and each twin's scalar equations equal to the
vectorized ones they mirror."""

from pathlib import Path

import numpy as np
import pytest

from circuitsim.netlist.reader import read_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.devices import junction

pytest.importorskip("numba")

GOLDEN = Path(__file__).parent / "golden_vendor"
# Time points may drift in round-off through the truncation-error test (divided differences of
# the charges): measured, bjt.cir's drift by up to 5.8e-8 of tstop with the same step counts,
# and the reference loop's own drift when reltol changes by 1e-14 relative is 2.6e-8 of tstop
SAME_TIME = 1e-7  # of tstop


@pytest.mark.parametrize(
    "name", ["poly_e.cir", "poly_g.cir", "poly_f.cir", "poly_h.cir", "jfet.cir", "bjt.cir"]
)
def test_compiled_kernel_takes_the_reference_loops_steps(name):
    circuit = read_netlist(GOLDEN / name)
    runs = {
        kernel: simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
        for kernel in ("python", "compiled")
    }
    reference, ours = runs["python"], runs["compiled"]
    assert ours.stats["kernel"] == "compiled"
    for count in ("accepted", "rejected", "newton_iterations"):
        assert ours.stats[count] == reference.stats[count], count
    tstop = circuit.transient.tstop
    assert ours.time.size == reference.time.size
    assert np.max(np.abs(ours.time - reference.time)) <= SAME_TIME * tstop
    for signal in reference.signals:
        span = max(float(np.ptp(reference[signal])), 1e-9)
        error = np.max(np.abs(np.interp(reference.time, ours.time, ours[signal])
                              - reference[signal]))  # fmt: skip
        assert error <= 1e-6 * span, f"{name}: {signal} {error / span:.3g} of its range"


VOLTS = np.concatenate([np.linspace(-5, 5, 401), [-0.0777, -0.0776, 0.0, 0.4, 0.5, 0.6]])


def test_junction_twins_equal_the_vectorized_equations():
    from circuitsim.solver.devices import junction_kernel as twin

    vt, isat, gmin = 0.0259, 1e-14, 1e-12
    current, slope = junction.junction_current(VOLTS, isat, vt, gmin)
    scalar = np.array([twin.junction_current(v, isat, vt, gmin) for v in VOLTS])
    np.testing.assert_allclose(scalar[:, 0], current, rtol=1e-14, atol=1e-30)
    np.testing.assert_allclose(scalar[:, 1], slope, rtol=1e-14, atol=1e-30)
    charge, capacitance = junction.depletion_charge(VOLTS, 4e-12, 0.8, 0.4, 0.5)
    scalar = np.array([twin.depletion_charge(v, 4e-12, 0.8, 0.4, 0.5) for v in VOLTS])
    np.testing.assert_allclose(scalar[:, 0], charge, rtol=1e-13, atol=1e-30)
    np.testing.assert_allclose(scalar[:, 1], capacitance, rtol=1e-13, atol=1e-30)
    # fetlim: every branch (old below, near and far above VTO; rising, falling, far)
    vto = -2.0
    old = np.repeat([-4.0, -2.3, -1.0, 0.5, 3.0], VOLTS.size)
    new = np.tile(VOLTS, 5)
    limited = junction.fetlim(new, old, np.full(new.size, vto))
    scalar = np.array([twin.fetlim(a, b, vto) for a, b in zip(new, old, strict=True)])
    np.testing.assert_array_equal(scalar, limited)
    assert np.count_nonzero(limited != new) > 100  # the limiting acted


def test_jfet_drain_current_twin_equals_the_family():
    from circuitsim.solver.devices.jfet_kernel import drain_current
    from circuitsim.solver.engine import build_system

    system = build_system(read_netlist(GOLDEN / "jfet.cir"), None)
    (family,) = [f for f in system.families if type(f).__name__ == "JfetFamily"]
    family.b = np.full(2, 0.7)  # the doping tail: every term of the equations
    family.b_factor = (1 - family.b) / (1.0 - family.vto)
    grid = np.linspace(-4, 4, 81)
    vgs, vgd = (a.ravel() for a in np.meshgrid(grid, grid))
    for k in range(2):
        m = vgs.size
        expected = family.__class__._drain_current(_one(family, k, m), vgs, vgd)
        scalar = np.array([
            drain_current(a, b, family.vto[k], family.beta[k], family.lam[k], family.b[k],
                          family.b_factor[k])
            for a, b in zip(vgs, vgd, strict=True)
        ])  # fmt: skip
        for j in range(3):
            np.testing.assert_allclose(scalar[:, j], expected[j], rtol=1e-13, atol=1e-18)


def _one(family, k, m):
    """A stand-in with element k's parameters repeated m times (for _drain_current)."""

    class One:
        pass

    one = One()
    for name in ("vto", "beta", "lam", "b", "b_factor"):
        setattr(one, name, np.full(m, getattr(family, name)[k]))
    return one


def test_a_failed_first_step_from_uic_goes_on_from_its_last_iterate(tmp_path):
    """The wheelset with the bipolar Boyle op-amp from uic: its first attempt fails and the
    retry starts where that attempt's Newton got to (solver/transient.py's retry_from), in
    both loops; the compiled one restarting from the initial conditions ended in "time step
    too small" at t = 4e-16 s."""
    from dataclasses import replace

    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.generate import generate
    from circuitsim.synthesis.options import SynthesisOptions

    library = Path(__import__("circuitsim").__file__).parent / "netlist/library/macromodels.lib"
    system = load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.040})
    options = SynthesisOptions(opamp="lib", opamp_lib=str(library), opamp_subckt="BOYLE_UA741",
                               series="exact", t_stop=1.0)  # fmt: skip
    circuit = read_netlist(generate(system, tmp_path / "w.cir", options).netlist)
    tran = circuit.transient
    circuit.analyses = [replace(tran, tstop=1e-6) if a is tran else a for a in circuit.analyses]
    runs = [
        simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
        for kernel in ("python", "compiled")
    ]
    assert runs[0].stats["rejected"] >= 1
    for count in ("accepted", "rejected", "newton_iterations"):
        assert runs[1].stats[count] == runs[0].stats[count], count
