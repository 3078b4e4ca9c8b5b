"""The compiled kernels on the generated wheelset netlist, against the reference loop
(solver/transient.py): the same steps, the same signals, and the refactor rules that keep
them fast (split from test_compiled_kernel.py)."""

from dataclasses import replace

import numpy as np
import pytest

from circuitsim.solver import SimulationOptions, simulate
from tests.solver.test_compiled_kernel import (
    KERNELS,
    SAME_SIGNAL,
    SAME_TIME,
    assert_kernels_agree,
    kernel_deviation,
)


def test_wheelset_kernels_agree(tmp_path):
    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.generate import generate
    from circuitsim.synthesis.options import SynthesisOptions

    model = load_model()
    system = model.system(parameters={"V": 55.0, "f": 3.0, "a": 0.040}, nonlinear={"flange": True})
    generated = generate(
        system,
        tmp_path / "wheelset.cir",
        SynthesisOptions(opamp="ideal", series="exact", t_stop=0.5),
    )
    circuit = generated.synthesis.circuit
    runs = {
        k: simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=k)) for k in KERNELS
    }
    python, compiled = runs["python"], runs["compiled"]
    assert compiled.stats["kernel"] == "compiled"
    # measured (0.5 s, 3905 steps on both): times within 2.3e-11 s, v(y) within 5.8e-13 of its
    # range; the worst signal is the flange comparator's switch node v(flange_abs2_s1) at
    # 2.6e-8 of its range (it sits at a switch threshold, where roundoff moves it most)
    assert_kernels_agree(python, compiled, bound=1e-6)
    assert kernel_deviation(python, compiled)["v(y)"] <= SAME_SIGNAL
    # The ports kernel tests Newton's convergence on the 4 junction voltages only (the
    # reference tests every unknown), so its iterates differ in round-off, and a step decision
    # on a knife's edge can fall the other way (most often the step that ends just short of a
    # switch's crossing, devices/switch.py: whether round-off puts the control past it):
    # measured the same 3879 steps and 17 rejections, the same time points up to t = 0.038 s
    # (305 steps), after that shifted by up to 2.3e-7 s; the states within 1.7e-8 of their
    # range. Where the time points agree, every signal agrees as for the compiled kernel;
    # past the shift, the integrator outputs (the states) differ by the interpolation across
    # it (v(y): 2.5e-8 of its range), while a comparator node that jumps when a diode turns
    # over differs by its jump wherever the shift moves the jump across a time point.
    ports = runs["ports"]
    assert ports.time.shape == python.time.shape
    assert ports.stats["rejected"] == python.stats["rejected"]
    assert np.max(np.abs(ports.time - python.time)) <= 1e-5 * python.time[-1]
    same = np.abs(ports.time - python.time) <= SAME_TIME * python.time[-1]
    assert same[: np.argmin(same)].size > 200
    for name in python.names:
        span = max(float(np.ptp(python[name])), 1e-12)
        assert np.max(np.abs(ports[name][same] - python[name][same])) <= 1e-6 * span, name
    for state in ("y", "psi", "y_dot", "psi_dot"):
        assert kernel_deviation(python, ports)[f"v({state})"] <= 1e-6


def test_wheelset_at_tight_tolerance_survives_the_first_steps(tmp_path):
    # Regression: at reltol 1e-6 with uic, the first step was cut (a switch transition located
    # against the uic start) to ~4e-14 s, where a0 is 1e5 times the factorization's; the
    # Woodbury update then lost the digits Newton needed on the op-amp branch currents and the
    # run failed with "time step too small" at t = 6e-16 s. A Newton failure that far from the
    # factored a0 is retried on a new factorization (transient.RETRY_RATIO), and the first step
    # from uic no longer locates a transition. The first step depends on tstop only through
    # min(tstop / 100, tstep), so 0.05 s starts exactly as the 5 s run does.
    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.options import SynthesisOptions
    from circuitsim.synthesis.translator import synthesize

    model = load_model()
    system = model.system(parameters={"V": 55.0, "f": 3.0, "a": 0.040}, nonlinear={"flange": True})
    circuit = synthesize(system, SynthesisOptions(series="exact", t_stop=5.0)).circuit
    tran = circuit.transient  # tstep = TMAX = 340 us, as for 5 s; stop after 0.05 s
    circuit.analyses = [replace(tran, tstop=0.05) if a is tran else a for a in circuit.analyses]
    runs = {
        k: simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=k, reltol=1e-6))
        for k in KERNELS
    }
    python, compiled = runs["python"], runs["compiled"]
    assert compiled.stats["kernel"] == "compiled"
    assert compiled.time[-1] == pytest.approx(0.05, abs=1e-12)
    assert kernel_deviation(python, compiled)["v(y)"] <= 1e-6
    assert runs["ports"].time[-1] == pytest.approx(0.05, abs=1e-12)
    # measured 6.0e-8 (no refinement check: the small systems are solved, not updated)
    assert kernel_deviation(python, runs["ports"])["v(y)"] <= 1e-6


def test_ports_kernel_refactors_when_the_junctions_leave_the_factored_conductances():
    """A uic start factors every junction at 0 V; the TL074 macromodels' output stages then
    settle far from there, leaving many active junctions in every Newton iteration. The ports
    kernel refactors at the present conductances once that persists (newton.REBASE_ACTIVE):
    without it, measured 0.89 s for the 5 s run on one factorization, with it 0.09 s."""
    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.options import SynthesisOptions
    from circuitsim.synthesis.translator import synthesize

    system = load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.04})
    circuit = synthesize(system, SynthesisOptions(opamp="tl074", series="exact", t_stop=0.05))
    circuit = circuit.circuit
    ports = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
    python = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="python"))
    assert ports.stats["factorizations"] >= 2
    for state in ("y", "psi", "y_dot", "psi_dot"):
        assert kernel_deviation(python, ports)[f"v({state})"] <= 1e-6
