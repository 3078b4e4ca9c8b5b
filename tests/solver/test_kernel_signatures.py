"""One machine code for every circuit: the compiled kernels' numba functions get no new
specialization (a compile of minutes) from a circuit of another shape."""

import numpy as np
import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import SimulationOptions, simulate

pytest.importorskip("numba")

# shapes that once gave an array of another dtype or layout: no conductance at all (an int64
# G), no time-dependent source, a PWL source, a switch alone, a diode without charge
CIRCUITS = {
    "current source into a capacitor": """* no conductance
I1 0 a DC 1m
C1 a 0 1u
.tran 1u 1m uic
.end
""",
    "pwl into rc": """* pwl
V1 in 0 PWL(0 0 1m 1 2m 0)
R1 in a 1k
C1 a 0 1u
.tran 10u 2m
.end
""",
    "switch and capacitor": """* switch only
V1 c 0 PULSE(0 1 0.2m 1u 1u 1 2)
I1 0 a DC 1m
S1 a 0 c 0 SWX
C1 a 0 1u IC=0
.model SWX SW(vt=0.5 ron=10 roff=1e9)
.tran 10u 1m uic
.end
""",
    "diode without charge": """* diode
V1 in 0 SIN(0 2 1k)
R1 in a 1k
D1 a 0 DX
C1 in 0 1n
.model DX D(is=1e-14)
.tran 10u 2m
.end
""",
}


def _signature_counts() -> dict[str, int]:
    from circuitsim.solver.compiled import time_loop

    kernels = {
        "time_loop.run_ports": time_loop.run_ports,
        "time_loop.run_mna": time_loop.run_mna,
    }
    return {name: len(function.signatures) for name, function in kernels.items()}


def test_no_new_kernel_specialization_for_a_circuit_of_another_shape():
    from circuitsim.solver.compiled import warm_up

    warm_up(("ports", "compiled"))
    before = _signature_counts()
    assert before == {"time_loop.run_ports": 1, "time_loop.run_mna": 1}  # one per kernel
    for name, text in CIRCUITS.items():
        circuit = parse_netlist(text)
        for kernel in ("ports", "compiled"):
            waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel=kernel))
            assert waves.stats["kernel"] == kernel, name
            assert np.all(np.isfinite(waves["v(a)"])), name
        assert _signature_counts() == before, name


def test_current_source_into_a_capacitor_ramps():
    # i = C dv/dt: 1 mA into 1 uF rises 1 V per ms (the circuit that compiled anew for 155 s)
    circuit = parse_netlist(CIRCUITS["current source into a capacitor"])
    waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
    assert np.max(np.abs(waves["v(a)"] - waves.time / 1e-3)) < 1e-9
