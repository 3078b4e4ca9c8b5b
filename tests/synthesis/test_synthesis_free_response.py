"""Amplitude 0 (the free response): no forcing source is needed, and the circuit still is the model.

The translator leaves a zero-amplitude sine source out; the mapping check must accept that
(a zero forcing term has nothing to realize) while still refusing a netlist that lacks the
source of a nonzero forcing. The circuit's free response from y0 = 5 mm (V = 55 m/s, below
the critical speed, so it decays without reaching the 9 mm flange clearance) is compared with
the direct ODE solution (scipy, mechanics room) as the translator's other tests do: %NRMSD on
y and y' at most 0.5. Our engine is compared from t > 0 only (its t = 0 point of a ``uic``
run is handled elsewhere); ngspice is the independent referee.
"""

import shutil

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.mechanics import load_model, solve
from circuitsim.netlist.circuit import Sin, VoltageSource
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis import ScaleMap, SynthesisOptions, check_mapping, generate

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

T_STOP = 1.0
SCENARIO = {"V": 55.0, "f": 3.0, "a": 0.0, "y0": 0.005}


def _free(tmp_path):
    system = load_model().system(parameters=SCENARIO)
    assert system.forcing and all(f.amplitude == 0.0 for f in system.forcing)
    result = generate(
        system, tmp_path / "free.cir", SynthesisOptions(series="exact", t_stop=T_STOP)
    )
    return system, result


def _sines(circuit) -> list[str]:
    return [
        e.name
        for e in circuit.elements
        if isinstance(e, VoltageSource) and isinstance(e.waveform, Sin)
    ]


def _nrmsd_after_start(waves, result, system) -> dict[str, float]:
    """%NRMSD per state against the ODE, on the engine's time points with t > 0."""
    reference = solve(system, (0.0, T_STOP))
    traces = map_waveforms(waves, ScaleMap.load(result.scale_file), ["y", "y_dot"])
    out = {}
    for state, (t, values) in traces.items():
        later = t > 0
        assert np.count_nonzero(later) > 100
        expected = reference.sol(t[later])[system.states.index(state)]
        out[state] = nrmsd_percent(expected, values[later])
    return out


def test_zero_amplitude_passes_the_mapping_check_without_a_source(tmp_path):
    _, result = _free(tmp_path)
    assert result.report.ok, result.report.problems
    assert not result.report.problems
    assert _sines(read_netlist(result.netlist)) == []  # the file really has no sine input


def test_a_missing_source_for_a_nonzero_amplitude_is_still_caught(tmp_path):
    _, result = _free(tmp_path)
    forced = load_model().system(parameters={**SCENARIO, "a": 0.040})
    report = check_mapping(result.netlist, result.scale_file, forced)
    assert not report.ok
    assert "forcing 1 into y_dot: not in the netlist" in report.problems


def test_generate_cli_with_amplitude_zero_reports_ok(tmp_path, capsys):
    out = tmp_path / "a0.cir"
    code = main(
        ["generate", "--amplitude", "0", "--param", "y0=0.005", "--tstop", "1", "-o", str(out)]
    )
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "mapping check: OK" in printed and "not in the netlist" not in printed


@requires_ngspice
@pytest.mark.ngspice
def test_free_response_in_ngspice_matches_the_ode(tmp_path):
    from circuitsim.interop.ngspice import run_ngspice

    system, result = _free(tmp_path)
    errors = _nrmsd_after_start(run_ngspice(result.netlist), result, system)
    assert errors["y"] <= 0.5 and errors["y_dot"] <= 0.5, errors


def test_free_response_on_our_solver_matches_the_ode(tmp_path):
    from circuitsim.solver import simulate

    system, result = _free(tmp_path)
    waves = simulate(read_netlist(result.netlist))
    errors = _nrmsd_after_start(waves, result, system)
    assert errors["y"] <= 0.5 and errors["y_dot"] <= 0.5, errors
