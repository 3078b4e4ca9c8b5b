"""A model written with every shorthand goes through generate, both engines and compare."""

import numpy as np
import pytest

from circuitsim.compare.case import run_case
from circuitsim.mechanics import load_model
from circuitsim.synthesis.options import SynthesisOptions
from tests.conftest import requires_ngspice

MODEL = """
[model]
name = "shorthands"
description = "forced oscillator: stop, saturating spring, rebound stop (table), friction (fit)"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
m = 1.0
wn = "2*pi*3"
k = "m*wn**2"
c = "2*0.05*m*wn"
F = "0.1*k"
f = 2.0
Fs = "0.02*k"
v0 = 0.2

[matrices]
M = [["m"]]
C = [["c"]]
K = [["k"]]

[nonlinear.stop]
enters = { x = 1 }
deadzone = { row = { x = 1 }, eta = 0.01, slope = "5*k" }

[nonlinear.spring]
enters = { x = 1 }
saturation = { row = { x = 1 }, limit = 0.02, slope = "0.5*k" }

[nonlinear.rebound]
enters = { x = 1 }
table = { row = { x = 1 }, breakpoints = [-0.015], slopes = ["2*k", 0] }

[nonlinear.friction]
enters = { x = 1 }
fit = { row = { x_dot = 1 }, function = "Fs*tanh(u/v0)", range = [-1, 1], max_error = "0.01*Fs" }

[forcing.drive]
amplitude = "F"
frequency = "f"
enters = { x = 1 }
"""


@pytest.mark.parametrize("engine", ["builtin", pytest.param("ngspice", marks=requires_ngspice)])
def test_every_shorthand_through_generate_simulate_and_compare(tmp_path, engine):
    path = tmp_path / "shorthands.toml"
    path.write_text(MODEL)
    system = load_model(path).system()
    assert [len(t.abs_terms) for t in system.nonlinear][:3] == [2, 2, 1]
    assert system.nonlinear[3].fits[0].max_error <= 0.01 * 0.02 * (6 * np.pi) ** 2
    result = run_case(
        system,
        SynthesisOptions(opamp="ideal", series="exact", t_stop=1.5),
        engine=engine,
        netlist=tmp_path / "shorthands.cir",
    )
    assert (tmp_path / "shorthands.cir").exists()
    for state, metrics in result.comparison.states.items():
        assert metrics.nrmsd_percent < 0.5, state
    # every piece was visited: past the stop, the saturation and the rebound stop
    x = result.reference["x"][1]
    assert x.max() > 0.02 and x.min() < -0.02


def test_the_blocks_of_a_fitted_function_share_one_argument_summer():
    # the creep correction: one row (y'/V - psi), ten breakpoints, one summer for all ten
    from circuitsim.synthesis.translator import synthesize

    system = load_model("wheelset_creep").system()
    (fit,) = system.nonlinear[0].fits
    names = [e.name for e in synthesize(system, peaks=False).circuit.elements]
    assert sum(name.startswith("XCREEP_ABS") and name.endswith("A") for name in names) == (
        fit.segments - 1
    )
    assert [name for name in names if name.startswith("XCREEP_ARG")] == ["XCREEP_ARG1"]


def test_ode_and_generate_report_the_fit(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    for verb in (["ode", "--tstop", "0.05"], ["generate", "-o", str(tmp_path / "c.cir")]):
        run = subprocess.run(
            [sys.executable, "-m", "circuitsim", *verb, "--model", "wheelset_creep"],
            cwd=root, capture_output=True, text=True, check=True,
        )  # fmt: skip
        line = next(x for x in run.stdout.splitlines() if x.startswith("fit creep: "))
        assert "12 pieces, max error 275 (allowed 300)" in line, line
