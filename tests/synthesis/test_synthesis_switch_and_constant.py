"""A constant input (b0) and a switch closing mid-run, against closed-form answers in ngspice."""

import shutil

import numpy as np
import pytest

from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.interop.ngspice import run_ngspice
from circuitsim.mechanics.system import AbsTerm, PiecewiseLinearTerm, System
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

TAU, B = 0.2, 3.0


def relaxation(t_on=None):
    """x' = -x / tau + b, plus (from t_on) a term -(1/tau) * |x|, i.e. x' = -2x/tau + b for x>0."""
    terms = ()
    if t_on is not None:
        terms = (
            PiecewiseLinearTerm(
                "extra", np.array([-1.0 / TAU]), np.zeros(1),
                (AbsTerm(1.0, np.array([1.0]), 0.0),), t_on=t_on,
            ),
        )  # fmt: skip
    return System(
        "relaxation", ("x",), ("V",), np.array([[-1.0 / TAU]]), np.array([B]), terms,
        x0=np.zeros(1), circuit_hints={"t_stop": 2.0},
    )  # fmt: skip


def closed_form(t, t_on=None):
    x = B * TAU * (1 - np.exp(-t / TAU))
    if t_on is None:
        return x
    x_on = B * TAU * (1 - np.exp(-t_on / TAU))
    final = B * TAU / 2  # x > 0 throughout: x' = -2x/tau + b
    after = final + (x_on - final) * np.exp(-2 * (t - t_on) / TAU)
    return np.where(t < t_on, x, after)


def test_constant_is_checked(tmp_path):
    result = generate(relaxation(), tmp_path / "r.cir", SynthesisOptions(series="E24"))
    assert result.report.ok, result.report.summary()
    (entry,) = [e for e in result.report.entries if e.what.startswith("b0")]
    assert entry.model == B and abs(entry.error) > 0  # E24-rounded, within the BOM's error


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("t_on", [None, 0.7])
def test_ngspice_matches_the_closed_form(tmp_path, t_on):
    options = SynthesisOptions(series="exact", time_scale=10.0)
    result = generate(relaxation(t_on), tmp_path / "r.cir", options)
    assert result.report.ok, result.report.summary()
    t, x = map_waveforms(run_ngspice(result.netlist), ScaleMap.load(result.scale_file))["x"]
    assert nrmsd_percent(closed_form(t, t_on), x) <= 0.2
