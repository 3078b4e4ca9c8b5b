"""Signal names and expressions the engine must read as ngspice does (issue 21 findings)."""

import numpy as np
import pytest

from circuitsim.netlist.reader import parse_netlist
from circuitsim.solver import simulate
from circuitsim.solver.errors import CircuitInputError


def test_an_expression_inside_a_waveform_is_evaluated_without_any_param():
    # SIN's amplitude {0.5*-1} = -0.5 V: v(a) = -0.5 sin(2 pi 50 t), a divider halves it.
    text = """waveform argument expression
V1 a 0 SIN(0 {0.5*-1} 50)
R1 a b 1k
R2 b 0 1k
.tran 0.1m 20m
.end
"""
    waves = simulate(parse_netlist(text))
    t = np.asarray(waves.time)
    expected = -0.25 * np.sin(2 * np.pi * 50 * t)
    assert np.max(np.abs(np.asarray(waves["v(b)"]) - expected)) < 1e-9


def test_the_kelvin_sign_node_keeps_its_own_signal_name():
    # U+212A and k are two nodes in ngspice (ASCII-only case folding): two dividers, two values.
    text = "kelvin\nV1 \u212a 0 1\nR1 \u212a 0 1k\nV2 k 0 2\nR2 k 0 1k\n.op\n.end\n"
    waves = simulate(parse_netlist(text))
    assert float(waves["v(\u212a)"][0]) == pytest.approx(1.0)
    assert float(waves["v(k)"][0]) == pytest.approx(2.0)


def test_an_unknown_probe_lists_a_bounded_number_of_signals():
    lines = ["many nodes", "V1 n0 0 1"]
    lines += [f"R{i} n{i} n{i + 1} 1k" for i in range(60)] + ["R60 n60 0 1k", ".op", ".end"]
    with pytest.raises(CircuitInputError) as info:
        simulate(parse_netlist("\n".join(lines)), probes=["v(nope)"])
    assert "no signal v(nope)" in str(info.value) and "in all)" in str(info.value)
    assert len(str(info.value)) < 400
