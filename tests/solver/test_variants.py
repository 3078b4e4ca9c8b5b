"""Many variants of one circuit (solver/variants.py): each equals its own single run on the
ports kernel (same steps, values to round-off), the RC variants their closed form; bad input
names the variant."""

import numpy as np
import pytest

from circuitsim.netlist.circuit import Capacitor, Circuit, Resistor, Transient, VoltageSource
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.engine import build_system
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.variants import resistor_changes, simulate_variants


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


def test_resistor_changes_finds_only_top_level_resistor_values():
    base = rc(1e3)
    assert resistor_changes(base, base) == {}
    assert resistor_changes(base, rc(2e3)) == {"R1": 2e3}
    other = rc(1e3)
    other.elements[2] = Capacitor("C1", "out", "0", 2e-6, ic=0.0)
    assert resistor_changes(base, other) is None  # a capacitor changed
    other = rc(2e3)
    other.elements[1] = Resistor("R1", "in", "mid", 2e3)
    assert resistor_changes(base, other) is None  # a node changed
    other = rc(1e3)
    other.analyses = [Transient(1e-5, 4e-3, uic=True)]
    assert resistor_changes(base, other) is None


def test_conductances_with_equals_assembling_the_changed_circuit():
    system = build_system(rc(1e3), None)
    changed = build_system(rc(3.3e3), None)
    np.testing.assert_array_equal(system.conductances_with({"R1": 3.3e3}), changed.G)
    np.testing.assert_array_equal(system.conductances_with({}), system.G)
    with pytest.raises(CircuitInputError, match="R9: no such element"):
        system.conductances_with({"R9": 1.0})
    with pytest.raises(CircuitInputError, match="C1: a CapacitorFamily value cannot change"):
        system.conductances_with({"C1": 1e-6})
    with pytest.raises(CircuitInputError, match="R1: resistance 0 is not allowed"):
        system.conductances_with({"R1": 0.0})


def test_variants_of_other_elements_or_without_uic_equal_their_single_runs():
    """The shared-assembly path (resistors only, uic) and the own-assembly path give each
    variant its single run: a capacitor variant and an operating-point start take the
    second."""
    wider = rc(1e3)
    wider.elements[2] = Capacitor("C1", "out", "0", 2e-6, ic=0.0)
    no_uic = [rc(r) for r in (1e3, 2e3)]
    for circuit in no_uic:
        circuit.analyses = [Transient(1e-5, 5e-3)]
    for circuits in ([rc(1e3), wider, rc(2e3)], no_uic):
        waves = simulate_variants(circuits, ["v(out)"], workers=2)
        for circuit, w in zip(circuits, waves, strict=True):
            single = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
            np.testing.assert_array_equal(w.time, single.time)
            span = np.ptp(single["v(out)"]) or 1.0
            np.testing.assert_allclose(w["v(out)"], single["v(out)"], rtol=0, atol=1e-12 * span)
            assert w.stats["factorizations"] == single.stats["factorizations"]


def test_a_bad_shared_variant_is_named():
    with pytest.raises(CircuitInputError, match="R1: resistance 0 is not allowed") as caught:
        simulate_variants([rc(1e3), rc(2e3), rc(0.0)], ["v(out)"], workers=1)
    assert "in variant 2 (0-based)" in caught.value.__notes__


def test_a_shared_start_takes_a_new_g_only_with_uic():
    from circuitsim.solver.compiled import ports_start, run_ports_from

    circuit = rc(1e3)
    system = build_system(circuit, None)
    start = ports_start(system, 1e-5, 5e-3, uic=False)
    with pytest.raises(ValueError, match="only for a uic start"):
        run_ports_from(start, system.G)


def test_variants_run_on_the_kernel_simulate_chooses():
    """``kernel="auto"`` (the default): the kernel ``simulate`` chooses for the base circuit,
    named in each variant's stats; the ideal quarter car's circuit (many switching junctions)
    runs on the MNA kernel, and each variant equals its own single ``simulate`` run."""
    from dataclasses import replace

    from circuitsim.mechanics import load_model
    from circuitsim.solver.variants import variants_kernel
    from circuitsim.synthesis.options import SynthesisOptions
    from circuitsim.synthesis.translator import synthesize

    model = load_model("quarter_car")
    base = synthesize(model.system(), SynthesisOptions(opamp="ideal", t_stop=0.5)).circuit
    assert variants_kernel(base) == "compiled" and variants_kernel(rc(1e3)) == "ports"
    assert variants_kernel(base, "ports") == "ports"
    with pytest.raises(CircuitInputError, match="kernel 'mna': expected auto, ports or comp"):
        variants_kernel(base, "mna")
    resistor = next(e for e in base.elements if isinstance(e, Resistor))
    other = replace(base, elements=[
        replace(e, resistance=1.1 * e.resistance) if e is resistor else e for e in base.elements
    ])  # fmt: skip
    probe = "v(" + next(e for e in base.elements if isinstance(e, Capacitor)).positive + ")"
    waves = simulate_variants([base, other], [probe], workers=2)
    for circuit, w in zip([base, other], waves, strict=True):
        assert w.stats["kernel"] == "compiled"
        single = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="auto"))
        assert single.stats["kernel"].startswith("compiled")
        np.testing.assert_array_equal(w.time, single.time)
        scale = np.max(np.abs(single.signals[probe]))
        np.testing.assert_allclose(w.signals[probe], single.signals[probe], atol=1e-12 * scale)
    assert simulate_variants([rc(1e3)], ["v(out)"])[0].stats["kernel"] == "ports"
