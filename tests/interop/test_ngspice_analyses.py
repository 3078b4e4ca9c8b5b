"""Decks with several analysis cards: ngspice runs exactly the one chosen, and it is right.

ngspice 39 aborts a ``run`` over an ``.op`` together with another analysis ("no data saved for
Transient analysis; analysis not run"), so the runner comments out every analysis card but the
chosen one. The circuit is an RC low-pass with a load: V1 (DC 3 for .op and .ac, a 0 -> 3 V
step for .tran) - R1 - out, with R2 and C1 from out to ground. Independent answers:

- .op: the divider, v(out) = 3 R2 / (R1 + R2) = 1 V, i(v1) = -3 / (R1 + R2);
- .tran: v(out) = 1 V (1 - exp(-t / tau)), tau = (R1 || R2) C, the Thevenin RC step;
- .ac (AC 1): H(f) = R2 / (R1 + R2) / (1 + j 2 pi f tau).
"""

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.interop.ngspice import _deck_lines, _with_control, run_ngspice
from circuitsim.solver.waveforms import Waveforms
from tests.conftest import requires_ngspice

R1, R2, C = 2e3, 1e3, 1e-6
TAU = R1 * R2 / (R1 + R2) * C  # 0.667 ms
DIVIDER = 3.0 * R2 / (R1 + R2)  # 1 V

HEAD = (
    "rc low-pass with a load, several analyses\n"
    "V1 in 0 DC 3 AC 1 PULSE(0 3 0 1n 1n 1 2)\n"
    "R1 in out 2k\n"
    "R2 out 0 1k\n"
    "C1 out 0 1u\n"
)
# Mixed case and continuation lines, as decks from other tools have them.
TRAN = ".TRAN 10u 3m\n+ 0 10u\n"
OP = ".Op\n"
AC = ".ac dec 5\n* the range on a line of its own\n+ 10 100k\n"


def _deck(*cards: str) -> str:
    return HEAD + "".join(cards) + ".end\n"


def _assert_rc_step(waves: Waveforms) -> None:
    assert waves.stats.get("analysis", "tran") == "tran"  # a CSV read back has no stats
    t = waves.time
    assert t[0] == 0.0 and t[-1] == pytest.approx(3e-3) and len(t) > 100
    after = t > 1e-6  # past the 1 ns rise
    exact = DIVIDER * (1.0 - np.exp(-t[after] / TAU))
    assert np.max(np.abs(waves["v(out)"][after] - exact)) < 1e-3


def _assert_divider(waves: Waveforms) -> None:
    assert waves.stats["analysis"] == "op"
    assert waves.time.tolist() == [0.0]
    assert waves["v(out)"][0] == pytest.approx(DIVIDER, rel=1e-9)
    assert waves["i(v1)"][0] == pytest.approx(-3.0 / (R1 + R2), rel=1e-9)


def _assert_lowpass(waves: Waveforms) -> None:
    assert waves.stats["analysis"] == "ac"
    f = waves.time
    assert f[0] == pytest.approx(10.0) and f[-1] == pytest.approx(1e5) and len(f) == 21
    h = R2 / (R1 + R2) / (1.0 + 2j * np.pi * f * TAU)
    assert np.allclose(waves["vm(out)"], np.abs(h), rtol=1e-9)
    assert np.allclose(waves["vp(out)"], np.degrees(np.angle(h)), atol=1e-7)


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("order", ["tran first", "op first"])
def test_tran_and_op_give_the_step_by_default_and_the_divider_when_asked(order):
    deck = _deck(TRAN, OP) if order == "tran first" else _deck(OP, TRAN)
    _assert_rc_step(run_ngspice(deck))
    _assert_divider(run_ngspice(deck, analysis="op"))
    _assert_rc_step(run_ngspice(deck, analysis="tran"))


@requires_ngspice
@pytest.mark.ngspice
def test_ac_and_tran_give_the_step_by_default_and_the_sweep_when_asked():
    deck = _deck(AC, TRAN)
    _assert_rc_step(run_ngspice(deck))
    _assert_lowpass(run_ngspice(deck, analysis="ac"))


@requires_ngspice
@pytest.mark.ngspice
def test_op_and_ac_give_either_one():
    deck = _deck(OP, AC)
    _assert_divider(run_ngspice(deck))  # .op before .ac by default
    _assert_divider(run_ngspice(deck, analysis="op"))
    _assert_lowpass(run_ngspice(deck, analysis="ac"))


@requires_ngspice
@pytest.mark.ngspice
def test_all_three_and_a_dc_sweep_in_one_file(tmp_path):
    path = tmp_path / "all.cir"
    path.write_text(_deck(OP, ".dc V1 0 3 1\n", AC, TRAN))
    _assert_rc_step(run_ngspice(path))
    _assert_divider(run_ngspice(path, analysis="op"))
    _assert_lowpass(run_ngspice(path, analysis="ac"))
    assert path.read_text() == _deck(OP, ".dc V1 0 3 1\n", AC, TRAN)  # the file is not touched


@requires_ngspice
@pytest.mark.ngspice
def test_cli_simulates_a_file_with_tran_and_op(tmp_path, capsys):
    path = tmp_path / "to.cir"
    path.write_text(_deck(".tran 10u 3m 0 10u\n", ".op\n"))
    csv = tmp_path / "to.csv"
    assert main(["simulate", str(path), "--engine", "ngspice", "--csv", str(csv)]) == 0
    capsys.readouterr()
    _assert_rc_step(Waveforms.from_csv(csv))


def test_only_the_chosen_card_is_left_for_ngspice():
    deck = (
        ".op title lines are never cards\n"
        "V1 in 0 DC 1\n"
        "  .TRAN 1u 1m\n"
        "+ 0 1u\n"
        "\n"
        "* a comment inside the card\n"
        "+ uic\n"
        ".options reltol=1e-4\n"
        ".Op\n"
        ".AC dec 5 10 100k\n"
        ".control\n"
        ".tran 1u 2m\n"
        "run\n"
        ".endc\n"
        "R1 in 0 1k\n"
        ".end\n"
    )
    lines = _deck_lines(deck)
    block = [".control", "set filetype=binary", "set measoutfile=meas.txt", "save all", "run"]
    block += ["write out.raw", ".endc", ".end"]
    assert (
        _with_control(lines, "op").splitlines()
        == [
            "circuitsim deck for ngspice",  # the title is ours, the deck's is dropped
            "V1 in 0 DC 1",  # the .TRAN card, its "+" lines and the comment between them: gone
            ".options reltol=1e-4",
            ".Op",
            "R1 in 0 1k",  # after the deck's own control block, which is gone with its .tran
            *block[:5],
            "setplot op1",
            *block[5:],
        ]
    )
    for kept, analysis in ((".TRAN 1u 1m", "tran"), (".AC dec 5 10 100k", "ac")):
        out = _with_control(lines, analysis).splitlines()
        assert kept in out and "R1 in 0 1k" in out and ".Op" not in out
        tran_lines = {"+ 0 1u", "+ uic"} <= set(out)
        assert tran_lines == (analysis == "tran")
        assert out[-9:] == [*block[:5], f"setplot {analysis}1", *block[5:]]
        assert ".tran 1u 2m" not in out
