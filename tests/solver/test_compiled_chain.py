"""The ports kernel on circuits that grow: chains of N masses with a dead-zone contact on
each (circuitsim.mechanics.chain; 4 diodes and about 40 unknowns per mass), against the
reference loop and ngspice, and the refactor rule that keeps their factorizations few."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from circuitsim.mechanics import load_model
from circuitsim.mechanics.chain import chain_model_text
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.solver.compiled import runner
from circuitsim.solver.compiled.sparse_factors import SPARSE_FROM
from circuitsim.solver.engine import build_system
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize
from tests.solver.conftest import requires_ngspice
from tests.solver.test_compiled_kernel import kernel_deviation


def chain_circuit(tmp_path, masses: int, t_stop: float, opamp: str = "ideal"):
    path = tmp_path / f"chain{masses}.toml"
    path.write_text(chain_model_text(masses, t_stop=5.0))
    model = load_model(path)
    system = model.system(nonlinear={group: True for group in model.nonlinear_terms})
    options = SynthesisOptions(opamp=opamp, series="exact", t_stop=5.0)
    circuit = synthesize(system, options).circuit
    tran = circuit.transient
    circuit.analyses = [replace(tran, tstop=t_stop) if a is tran else a for a in circuit.analyses]
    return circuit


@pytest.mark.parametrize("kernel", ["ports", "compiled"])
def test_sparse_factorization_agrees_with_the_reference_loop(tmp_path, kernel):
    """Four masses: 162 unknowns (the ports kernel factors sparse: above SPARSE_FROM;
    the MNA kernel refactors sparse at every iteration), 16 junctions."""
    circuit = chain_circuit(tmp_path, 4, 0.5)
    ports = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
    assert ports.stats["kernel"] == kernel
    assert ports.stats["unknowns"] >= SPARSE_FROM
    python = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="python"))
    devs = kernel_deviation(python, ports)
    worst = max(devs, key=devs.get)
    # the states' nodes (a comparator node that a shifted time point crosses differs more:
    # measured 0.14 of its range). The kernels' Newton tests differ (docs/solver.md), so their
    # accepted points do after a while; measured 7e-6 to 3.7e-5 of the range: bound a tenth
    # of reltol (1e-3)
    states = {name: dev for name, dev in devs.items() if name.startswith("v(x")}
    assert states and max(states.values()) <= 1e-4, (worst, devs[worst])


def test_the_wide_chord_halves_the_refactors_at_the_same_steps(tmp_path, monkeypatch):
    """Four masses (162 unknowns, from plan.WIDE_CHORD_FROM): the MNA kernel's wide chord
    against the narrow one (plan.CHORD_TOLERANCE): measured 483 against 939 refactors, the
    same 399 steps and 994 Newton iterations, the states within 1e-7 of their range."""
    from circuitsim.solver.compiled import plan

    circuit = chain_circuit(tmp_path, 4, 0.5)
    options = SimulationOptions.from_circuit(circuit, kernel="compiled")
    wide = simulate(circuit, options)
    assert wide.stats["unknowns"] >= plan.WIDE_CHORD_FROM
    monkeypatch.setattr(plan, "WIDE_CHORD_TOLERANCE", plan.CHORD_TOLERANCE)
    narrow = simulate(circuit, options)
    assert wide.stats["factorizations"] < 0.6 * narrow.stats["factorizations"]
    assert abs(wide.stats["accepted"] - narrow.stats["accepted"]) <= 0.01 * narrow.stats["accepted"]
    newton = narrow.stats["newton_iterations"]
    assert abs(wide.stats["newton_iterations"] - newton) <= 0.02 * newton
    devs = kernel_deviation(narrow, wide)
    states = {name: dev for name, dev in devs.items() if name.startswith("v(x")}
    # a tenth of reltol (1e-3), as against the reference loop above
    assert states and max(states.values()) <= 1e-4


def test_refactors_stay_few_as_junctions_grow(tmp_path):
    """Half of a precision rectifier's junctions conduct and keep changing their conductance,
    so a refactor cannot leave fewer active than that; the rule is relative to what the last
    refactor left (newton.rebase_wanted). With the absolute rule (more than 8 active) the
    four-mass chain's 5 s run measured 505 factorizations, with this one 7-13."""
    circuit = chain_circuit(tmp_path, 4, 5.0)
    ports = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
    assert ports.stats["kernel"] == "ports"
    assert ports.stats["factorizations"] <= 30
    assert ports.stats["accepted"] >= 3000  # the run did its work (measured 4080 steps)


@requires_ngspice
def test_large_chain_runs_compiled_and_agrees_with_ngspice(tmp_path):
    """Sixteen masses: 642 unknowns, 64 junctions with charge; auto runs the MNA kernel
    (runner.auto_kernel: more than 12 such junctions) and it agrees with ngspice."""
    from circuitsim.interop.ngspice import run_ngspice

    circuit = chain_circuit(tmp_path, 16, 0.5)
    ours = simulate(circuit)
    assert ours.stats["kernel"] == "compiled"
    assert ours.stats["unknowns"] > 600
    probes = ["v(x1)", "v(x16)"]
    theirs = run_ngspice(circuit, probes)
    for name in probes:
        span = float(np.ptp(theirs[name]))
        mine = np.interp(theirs.time, ours.time, ours[name])
        # the golden netlists' bound against ngspice (tests/solver/test_golden.py: 1e-3)
        assert np.max(np.abs(mine - theirs[name])) <= 1e-3 * span, name


@pytest.mark.parametrize(
    ("masses", "opamp", "charged", "eliminated", "kernel"),
    [
        (4, "ideal", 16, 12, "compiled"),
        (1, "ideal", 4, 3, "ports"),
        (8, "ideal", 32, 24, "compiled"),
        (2, "tl074", 8, 24, "ports"),
        (4, "tl074", 16, 48, "compiled"),
    ],
)
def test_auto_kernel_rule(tmp_path, masses, opamp, charged, eliminated, kernel):
    """runner.auto_kernel on the scaling benchmark's chains: the ports kernel up to 12 charged
    junctions and 32 eliminated ports (switches and linear charges), the MNA kernel beyond
    either (docs/solver.md, "Choosing the kernel": the MNA kernel measured 1.17x faster on
    the 4-mass ideal chain, 2.4x on the 8-mass one and 2.1x on the 4-mass TL074 chain; the
    ports kernel 2.1x on the 1-mass ideal chain, as fast on the 2-mass TL074 chain)."""
    circuit = chain_circuit(tmp_path, masses, 0.1, opamp)
    system = build_system(circuit, SimulationOptions.from_circuit(circuit))
    assert runner.switching_junctions(system) == charged
    assert runner.eliminated_ports(system) == eliminated
    assert runner.auto_kernel(system) == kernel
