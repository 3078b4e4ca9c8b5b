"""Many variants of one circuit (solver/variants.py): each equals its own single run on the
ports kernel (same steps, values to round-off), the RC variants their closed form; bad input
names the variant."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import Capacitor, Circuit, Resistor, Transient, VoltageSource
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.variants import simulate_variants


def rc(r: float, tran: bool = True) -> Circuit:
    return Circuit(
        elements=[
            VoltageSource("V1", "in", "0", dc=1.0),
            Resistor("R1", "in", "out", r),
            Capacitor("C1", "out", "0", 1e-6, ic=0.0),
        ],
        analyses=[Transient(1e-5, 5e-3, uic=True)] if tran else [],
    )


def test_variants_equal_their_single_runs_and_the_closed_form():
    resistances = [500.0, 1e3, 2e3, 4e3, 8e3]
    done = []
    waves = simulate_variants(
        [rc(r) for r in resistances],
        ["v(out)", "i(v1)"],
        workers=2,
        progress=lambda k, total: done.append((k, total)),
    )
    assert done[-1] == (5, 5) and len(done) == 5
    for r, w in zip(resistances, waves, strict=True):
        circuit = rc(r)
        single = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
        np.testing.assert_array_equal(w.time, single.time)
        for name in ("v(out)", "i(v1)"):  # to round-off: formed row by row, not by columns
            span = np.ptp(single[name])
            np.testing.assert_allclose(w[name], single[name], rtol=0, atol=1e-12 * span)
        assert w.stats["kernel"] == "ports"
        exact = 1 - np.exp(-w.time / (r * 1e-6))
        assert np.max(np.abs(w["v(out)"] - exact)) < 2e-3


def test_variant_errors_name_the_variant():
    with pytest.raises(CircuitInputError, match=r"variant 1: the circuit has no \.tran"):
        simulate_variants([rc(1e3), rc(2e3, tran=False)], ["v(out)"], workers=1)
    with pytest.raises(CircuitInputError, match=r"variant 0: no signal v\(nowhere\)"):
        simulate_variants([rc(1e3)], ["v(nowhere)"], workers=1)
    resistive = Circuit(
        elements=[VoltageSource("V1", "a", "0", dc=1.0), Resistor("R1", "a", "0", 1e3)],
        analyses=[Transient(1e-5, 1e-3)],
    )
    with pytest.raises(CircuitInputError, match="variant 0: the ports kernel cannot run it"):
        simulate_variants([resistive], ["v(a)"], workers=1)
