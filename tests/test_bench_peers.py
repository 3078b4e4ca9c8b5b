"""The peers benchmark's helpers (benchmarks/bench_peers.py): gnucap's printed table, the
VACASK writer, and both peers on an RC circuit against its analytic solution."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_peers  # noqa: E402

from circuitsim.netlist.reader import parse_netlist  # noqa: E402

GNUCAP_OUTPUT = """\
Gnucap : The Gnu Circuit Analysis Package
main version: master 2017.10.03
* rc
.ic v(out)=0.2
 ^ ? ic: no match
#Time       v(out)     v(a)
 0.         0.         1.
 270.u      2.725u    -43.147p
 270.u      2.725u    -43.147p
 0.00108    164.25u    1.5K
 4.9999     0.26295    3Meg
.save v(out)
^ ? can't find
"""

# An RC charging through a switch that a DC source holds closed (ron = 1 ohm), from 0.2 V on
# the capacitor: v(out) = 1 - 0.8 exp(-t / tau), tau = (1000 + 1) ohm x 1 uF.
RC = """\
* rc with a switch held closed
.model SW1 SW(vt=0.5 vh=0 ron=1 roff=1t)
V1 in 0 DC 1
VCTL ctl 0 DC 1
S1 in a ctl 0 SW1
R1 a out 1k
C1 out 0 1u IC=0.2
.print tran v(out)
.tran 10u 5m 0 10u uic
.end
"""
TAU = 1001.0 * 1e-6


def rc_exact(t: np.ndarray) -> np.ndarray:
    return 1.0 - 0.8 * np.exp(-t / TAU)


def test_gnucap_table_is_read_with_suffixes_and_a_repeated_point_dropped():
    waves = bench_peers.parse_gnucap_print(GNUCAP_OUTPUT)
    assert waves.names == ["v(out)", "v(a)"]
    np.testing.assert_allclose(waves.time, [0.0, 270e-6, 1.08e-3, 4.9999], rtol=1e-15)
    np.testing.assert_allclose(waves["v(out)"], [0.0, 2.725e-6, 164.25e-6, 0.26295], rtol=1e-15)
    np.testing.assert_allclose(waves["v(a)"], [1.0, -43.147e-12, 1500.0, 3e6], rtol=1e-15)


def test_gnucap_output_without_a_table_or_with_a_short_row_is_refused():
    with pytest.raises(ValueError, match="no '#Time' header"):
        bench_peers.parse_gnucap_print("Gnucap\n.tran 1 2\n")
    with pytest.raises(ValueError, match="line 3: 2 columns, expected 3"):
        bench_peers.parse_gnucap_print("x\n#Time v(a) v(b)\n 0. 1.\n")


def test_capacitor_ic_becomes_node_voltages_and_a_contradiction_is_refused():
    circuit = parse_netlist(
        "* t\nC1 a b 1u IC=-1.5\nC2 c 0 1u IC=0.5\nC3 d e 1u IC=2\nR1 a 0 1\n.ic v(a)=1\n.end\n"
    )
    assert bench_peers.initial_voltages(circuit) == {
        "a": 1.0, "b": 2.5, "c": 0.5, "d": 2.0, "e": 0.0
    }  # fmt: skip
    wrong = parse_netlist("* t\nC1 a 0 1u IC=1\nR1 a 0 1\n.ic v(a)=2\n.end\n")
    with pytest.raises(ValueError, match="C1: IC=1 V against .ic 2"):
        bench_peers.initial_voltages(wrong)


def test_vacask_writer_names_what_it_cannot_write(tmp_path):
    netlist = tmp_path / "l.cir"
    netlist.write_text("* l\nV1 a 0 DC 1\nL1 a b 1m\nR1 b 0 1\n.tran 1u 1m\n.end\n")
    with pytest.raises(ValueError, match="L1: no VACASK form"):
        bench_peers.vacask_text(netlist, ["b"])


@pytest.mark.skipif(bench_peers.vacask_program() is None, reason="VACASK not installed")
def test_vacask_runs_the_written_rc_to_its_analytic_solution(tmp_path):
    netlist = tmp_path / "rc.cir"
    netlist.write_text(RC)
    text = bench_peers.vacask_text(netlist, ["out"])
    assert "s1 (in a) r r=1.0" in text  # the switch held closed: its on-resistance
    sim = tmp_path / "rc.sim"
    sim.write_text(text)
    result = bench_peers.vacask_run(sim, ["out"])
    assert "error" not in result, result.get("error")
    waves = result["waves"]
    assert waves.time[-1] == pytest.approx(5e-3)
    assert np.max(np.abs(waves["v(out)"] - rc_exact(waves.time))) < 1e-4  # of a 0.8 V range


@pytest.mark.skipif(bench_peers.shutil.which("gnucap") is None, reason="gnucap not installed")
def test_gnucap_runs_the_rc_to_its_analytic_solution(tmp_path):
    netlist = tmp_path / "rc.cir"
    netlist.write_text(RC)
    result = bench_peers.gnucap_run(netlist)
    assert "error" not in result, result.get("error")
    waves = result["waves"]
    assert waves.time[0] == pytest.approx(10e-6)  # its t = 0 row (before IC=) is dropped
    assert waves.time[-1] == pytest.approx(5e-3)
    assert np.max(np.abs(waves["v(out)"] - rc_exact(waves.time))) < 1e-4


def test_a_process_past_the_cpu_limit_is_a_row_not_a_hang(tmp_path):
    done = bench_peers.child_run([sys.executable, "-c", "while True: pass"], tmp_path, cpu_limit=1)
    result = bench_peers._timed_out({"returncode": done["returncode"]})
    assert result["error"] == f"stopped at the CPU limit ({bench_peers.CPU_LIMIT_S} s)"
    assert 0.9 < done["cpu_s"] < 10.0
