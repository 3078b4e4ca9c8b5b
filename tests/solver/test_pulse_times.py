"""PULSE with negative times: a negative delay as ngspice 39 reads it; negative spans refused."""

import numpy as np
import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import simulate
from circuitsim.solver.errors import CircuitInputError
from tests.solver.conftest import requires_ngspice

NETLIST = """* pulse
V9 a 0 PULSE({spec})
R1 a 0 1k
.tran 10u 5m
.end
"""


def ngspice_pulse(t, v1, v2, td, tr, tf, pw, per):
    """vsrcload.c's PULSE, written out: shift by TD, fold into the period, then the corners."""
    tau = t - td
    tau = np.where(tau > per, tau - per * np.floor(tau / per), tau)
    return np.select(
        [(tau <= 0) | (tau >= tr + pw + tf), (tau >= tr) & (tau <= tr + pw), tau < tr],
        [v1, v2, v1 + (v2 - v1) * tau / tr],
        v2 + (v1 - v2) * (tau - tr - pw) / tf,
    )


def test_negative_delay_shifts_the_pulse_train_earlier():
    waves = simulate(parse_netlist(NETLIST.format(spec="0 1 -0.3m 10u 20u 1m 2m")))
    want = ngspice_pulse(waves.time, 0.0, 1.0, -0.3e-3, 10e-6, 20e-6, 1e-3, 2e-3)
    assert np.max(np.abs(waves["v(a)"] - want)) < 1e-12
    # on at t = 0 (0.3 ms into the first pulse), falling 0.71-0.73 ms, rising 1.7-1.71 ms
    assert waves["v(a)"][0] == 1.0
    for corner in (0.71e-3, 0.73e-3, 1.7e-3, 1.71e-3):
        assert np.min(np.abs(waves.time - corner)) < 1e-12, corner


@requires_ngspice
def test_negative_delay_agrees_with_ngspice():
    from circuitsim.interop.ngspice import run_ngspice

    text = NETLIST.format(spec="0 1 -0.3m 10u 20u 1m 2m")
    theirs = run_ngspice(text, probes=["v(a)"])
    want = ngspice_pulse(theirs.time, 0.0, 1.0, -0.3e-3, 10e-6, 20e-6, 1e-3, 2e-3)
    assert np.max(np.abs(theirs["v(a)"] - want)) < 1e-9  # the formula is ngspice's
    ours = simulate(parse_netlist(text))
    assert np.max(np.abs(np.interp(theirs.time, ours.time, ours["v(a)"]) - theirs["v(a)"])) < 1e-9


@pytest.mark.parametrize(
    "spec, key",
    [
        ("0 1 0.2m -10u 10u 1m 2m", "rise"),
        ("0 1 0.2m 10u -10u 1m 2m", "fall"),
        ("0 1 0.2m 10u 10u -1m 2m", "width"),
        ("0 1 0.2m 10u 10u 0.5m -2m", "period"),
    ],
)
def test_negative_spans_are_refused_naming_the_source(spec, key):
    with pytest.raises(CircuitInputError, match=f"V9: PULSE {key} -"):
        simulate(parse_netlist(NETLIST.format(spec=spec)))
