"""The netlist's step from the stiffest segment (synthesis/timestep.py).

The impact oscillator (tests/synthesis/models/impact_oscillator.toml) hits a stop 500 times
stiffer than its spring: its contact mode, sqrt((k + kc) / m) / 2 pi = 112.6 Hz, is 22 times
the free spring's. A step from the linear part (the stop open) gave 4.0 % (ngspice) and 3.2 %
(builtin) NRMSD on this model; the step from the contact mode must bring both under 0.5 %.
"""

import math
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from circuitsim.compare.case import run_case
from circuitsim.mechanics import load_model
from circuitsim.mechanics.system import AbsTerm, PiecewiseLinearTerm, System
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.timestep import MAX_REGIONS, choose_step, fastest_mode
from circuitsim.synthesis.translator import synthesize

MODELS = Path(__file__).parent / "models"
requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def impact():
    return load_model(MODELS / "impact_oscillator.toml")


def test_the_contact_mode_sets_the_step():
    model = impact()
    system = model.system()
    p = model.parameters
    kc = p["kc_ratio"] * p["k"]
    # the contact region's undamped frequency, and its damped |lambda| = sqrt((k + kc) / m)
    assert fastest_mode(system)[0] == pytest.approx(math.sqrt((p["k"] + kc) / p["m"]), 1e-12)
    step = choose_step(system, 1.0, 5.0, 200)
    assert "stop |x| 1 > 0" in step.source
    assert step.tmax == float(f"{1 / (200 * math.sqrt(p['k'] + kc) / (2 * math.pi)):.2g}")
    circuit = synthesize(system, SynthesisOptions(series="exact")).circuit
    assert circuit.transient.tmax == step.tmax


def test_an_unreachable_region_is_not_counted():
    # the gap oscillator's dead zone: below -d and above +d at once would be slope 2 kg
    model = load_model(MODELS / "gap_oscillator.toml")
    p = model.parameters
    system = model.system(parameters={"kg": 40000.0})
    rate, source = fastest_mode(system)
    assert rate == pytest.approx(math.sqrt((p["k"] + 40000.0) / p["m"]), rel=1e-3)
    assert "gap |x| 1 > 0, gap |x| 2 > 0" in source or "gap |x| 1 < 0, gap |x| 2 < 0" in source


def test_a_term_that_never_acts_does_not_set_the_step():
    system = impact().system()
    terms = tuple(replace(t, t_on=math.inf) for t in system.nonlinear)
    never = replace(system, nonlinear=terms)
    assert fastest_mode(never)[0] == pytest.approx(np.max(np.abs(np.linalg.eigvals(system.A))))


def test_many_regions_use_a_bound_above_every_region():
    # a chain of springs with a stop on each: 2^9 regions > MAX_REGIONS
    n = 9
    K = 2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -0.1 * np.eye(n)]])
    terms = []
    for i in range(n):
        row, direction = np.zeros(2 * n), np.zeros(2 * n)
        row[i], direction[n + i] = 1.0, -1.0
        terms.append(PiecewiseLinearTerm(f"s{i}", direction, 50.0 * row,
                                         (AbsTerm(50.0, row, -0.1),), -5.0))  # fmt: skip
    system = System("chain", tuple(f"x{i}" for i in range(2 * n)), ("",) * 2 * n, A,
                    np.zeros(2 * n), tuple(terms))  # fmt: skip
    assert 2**n > MAX_REGIONS
    rate, source = fastest_mode(system)
    assert "bound" in source
    # every stop in contact: stiffness 100 added on each mass
    contact = A.copy()
    contact[n:, :n] -= 100.0 * np.eye(n)
    assert rate >= np.max(np.abs(np.linalg.eigvals(contact)))


@pytest.mark.parametrize(
    "engine", ["builtin", pytest.param("ngspice", marks=[requires_ngspice, pytest.mark.ngspice])]
)
def test_impact_oscillator_circuit_matches_the_ode(engine):
    system = impact().system()
    case = run_case(system, SynthesisOptions(series="exact"), engine)
    for state, metrics in case.comparison.states.items():
        assert metrics.nrmsd_percent <= 0.5, (engine, state, metrics.nrmsd_percent)


@pytest.mark.parametrize("duration", [1e-3, 0.25, 1e200])
def test_bump_sampling_bounds_the_interpolation_error_for_any_duration(duration):
    """h^2/8 max|u''| equals the allowed error (haversine u = (1 - cos(2 pi s))/2, per unit
    amplitude: max|u''| = 2 pi^2 / duration^2); a duration of 1e200 s gave an OverflowError
    (found by the fuzz campaign, seed 20261203)."""
    from types import SimpleNamespace

    from circuitsim.synthesis.timestep import bump_spacing

    bump = SimpleNamespace(shape="haversine", duration=duration)
    h = bump_spacing(bump, 1e-3)
    assert math.isfinite(h)
    # the bound in relative form, (h/duration)^2 / 8 * 2 pi^2 = error, which cannot overflow
    assert (h / duration) ** 2 / 8 * 2 * math.pi**2 == pytest.approx(1e-3, rel=1e-12)
