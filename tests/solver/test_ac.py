"""Small-signal .ac analysis: analytic transfer functions, SPICE's frequency grid, ngspice.

Independent answers: each circuit's transfer function written out by hand (RC, series RLC,
a current source into a resistor, a diode's small-signal conductance and depletion
capacitance from SPICE's own formulas at the operating point, a switch's on and off
resistances); ngspice's .ac on the golden netlists and on the wheelset circuits.
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.netlist.circuit import AcSweep
from circuitsim.netlist.reader import parse_netlist, read_netlist
from circuitsim.solver import ac_analysis, simulate
from circuitsim.solver.ac import ac_frequencies
from circuitsim.solver.errors import CircuitInputError
from circuitsim.solver.waveforms import Waveforms
from tests.conftest import requires_ngspice

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = sorted((ROOT / "tests" / "solver" / "golden").glob("*.cir"))
VENDOR = sorted((ROOT / "tests" / "solver" / "golden_vendor").glob("*.cir"))
WHEELSETS = [
    ROOT / "netlists" / f"wheelset_{c}_ngspice.cir"
    for c in ("flange_ideal", "flange_tl074", "linear_tl074")
]


def _run(text: str) -> Waveforms:
    return simulate(parse_netlist(text))


def test_rc_low_pass_with_a_load_is_its_transfer_function_on_spice_s_grid():
    r1, r2, c = 2e3, 1e3, 1e-6
    text = (
        "rc\nV1 in 0 DC 3 AC 1\nR1 in out 2k\nR2 out 0 1k\nC1 out 0 1u\n.ac dec 5 10 100k\n.end\n"
    )
    waves = _run(text)
    f = waves.time
    assert waves.axis == "frequency" and waves.stats["analysis"] == "ac"
    assert len(f) == 21 and f[0] == 10.0 and f[-1] == pytest.approx(1e5, rel=1e-12)
    assert np.allclose(np.diff(np.log10(f)), 0.2, rtol=1e-12)
    h = r2 / (r1 + r2) / (1 + 2j * np.pi * f * (r1 * r2 / (r1 + r2)) * c)
    assert np.allclose(waves["vm(out)"], np.abs(h), rtol=1e-12)
    assert np.allclose(waves["vp(out)"], np.degrees(np.angle(h)), atol=1e-10)
    assert np.allclose(waves["vm(in)"], 1.0) and np.allclose(waves["vp(in)"], 0.0)


def test_series_rlc_voltage_and_source_current():
    r, inductance, c = 20.0, 10e-3, 1e-6
    text = "rlc\nV1 in 0 AC 1\nR1 in a 20\nL1 a b 10m\nC1 b 0 1u\n.ac lin 50 100 5k\n.end\n"
    waves = _run(text)
    w = 2 * np.pi * waves.time
    vc = 1 / (1 - w**2 * inductance * c + 1j * w * r * c)
    i_v1 = -1 / (r + 1j * w * inductance + 1 / (1j * w * c))  # SPICE: n+ through the source
    assert np.allclose(waves["vm(b)"], np.abs(vc), rtol=1e-11)
    assert np.allclose(waves["vp(b)"], np.degrees(np.angle(vc)), atol=1e-9)
    assert np.allclose(waves["im(v1)"], np.abs(i_v1), rtol=1e-11)
    assert np.allclose(waves["ip(v1)"], np.degrees(np.angle(i_v1)), atol=1e-9)
    assert np.allclose(np.diff(waves.time), 100.0) and waves.time[-1] == pytest.approx(5e3)


def test_a_current_source_s_magnitude_and_phase_and_a_controlled_source():
    # I1 from 0 through the source into a: 2 mA at 90 degrees into 1 kOhm; E1 doubles it
    text = "i\nI1 0 a AC 2m 90\nR1 a 0 1k\nE1 b 0 a 0 -2\nR2 b 0 1k\n.ac oct 2 1 16\n.end\n"
    waves = _run(text)
    assert len(waves.time) == 9 and waves.time[-1] == pytest.approx(16.0)
    assert np.allclose(waves["vm(a)"], 2.0) and np.allclose(waves["vp(a)"], 90.0)
    assert np.allclose(waves["vm(b)"], 4.0) and np.allclose(waves["vp(b)"], -90.0)


def test_a_forward_diode_is_its_small_signal_conductance_and_depletion_capacitance():
    isat, n, cjo, vj, m = 1e-14, 1.0, 10e-12, 0.7, 0.4
    text = (
        "diode\nV1 in 0 DC 0.3 AC 1\nR1 in a 1k\nD1 a 0 dm\n"
        f".model dm D(IS={isat} N={n} CJO={cjo} VJ={vj} M={m})\n.ac dec 10 1k 100meg\n.end\n"
    )
    waves = _run(text)
    vd = simulate(parse_netlist(text.replace(".ac dec", ".op\n.ac dec")))["v(a)"][0]
    vt = 1.380649e-23 * 300.15 / 1.602176634e-19
    gmin = 1e-12
    gd = isat / (n * vt) * math.exp(vd / (n * vt)) + gmin
    cj = cjo / (1 - vd / vj) ** m  # vd < FC * VJ: the power law
    h = 1 / (1 + 1e3 * (gd + 2j * np.pi * waves.time * cj))
    assert 0.0 < vd < 0.5 * vj
    assert np.allclose(waves["vm(a)"], np.abs(h), rtol=1e-8)
    assert np.allclose(waves["vp(a)"], np.degrees(np.angle(h)), atol=1e-6)


@pytest.mark.parametrize(("control", "closed"), [(1.0, True), (0.0, False)])
def test_a_switch_is_in_its_operating_point_state(control, closed):
    text = (
        f"switch\nV1 a 0 AC 1\nS1 a b c 0 swm\nVc c 0 DC {control}\nR1 b 0 1k\n"
        ".model swm SW(vt=0.5 vh=0 ron=10 roff=1meg)\n.ac lin 3 1 10\n.end\n"
    )
    r_switch = 10.0 if closed else 1e6
    assert np.allclose(_run(text)["vm(b)"], 1e3 / (1e3 + r_switch), rtol=1e-12)


@pytest.mark.parametrize(
    ("card", "expected"),
    [
        (AcSweep("lin", 5, 1.0, 5.0), [1.0, 2.0, 3.0, 4.0, 5.0]),
        (AcSweep("lin", 2, 1.0, 5.0), [1.0]),  # ngspice: a step only from 3 points
        (AcSweep("lin", 4, 3.0, 3.0), [3.0]),
        (AcSweep("oct", 1, 1.0, 8.0), [1.0, 2.0, 4.0, 8.0]),
        (AcSweep("dec", 1, 1.0, 1000.0), [1.0, 10.0, 100.0, 1000.0]),
        (AcSweep("dec", 3, 2.0, 2.0), [2.0]),
    ],
)
def test_the_frequency_grid_is_spice_s(card, expected):
    assert np.allclose(ac_frequencies(card), expected, rtol=1e-12)


@pytest.mark.parametrize(
    ("card", "message"),
    [
        (AcSweep("log", 5, 1.0, 5.0), "dec, oct or lin"),
        (AcSweep("dec", 0, 1.0, 5.0), "at least 1"),
        (AcSweep("dec", 5, 0.0, 5.0), "start frequency > 0"),
        (AcSweep("lin", 5, 10.0, 5.0), "at least the start"),
        (AcSweep("dec", 10**6, 1.0, 1e9), "more than"),
    ],
)
def test_a_bad_sweep_is_refused_by_name(card, message):
    with pytest.raises(CircuitInputError, match=message):
        ac_frequencies(card)


def test_the_analysis_is_chosen_as_ngspice_chooses_it():
    base = "rc\nV1 in 0 DC 1 AC 1\nR1 in out 1k\nC1 out 0 1u\n"
    assert _run(base + ".ac dec 5 10 10k\n.end\n").axis == "frequency"  # .ac alone
    both = parse_netlist(base + ".op\n.ac dec 5 10 10k\n.end\n")
    assert simulate(both).time.tolist() == [0.0]  # .op before .ac
    assert len(simulate(both, analysis="ac").time) == 16
    with pytest.raises(CircuitInputError, match=r"no \.tran card"):
        simulate(both, analysis="tran")
    with pytest.raises(CircuitInputError, match="no .ac card"):
        ac_analysis(parse_netlist(base + ".op\n.end\n"))


def test_probes_give_magnitude_and_phase_and_unknown_probes_are_refused():
    circuit = parse_netlist("rc\nV1 in 0 AC 1\nR1 in out 1k\nC1 out 0 1u\n.ac dec 2 1 1k\n.end\n")
    assert ac_analysis(circuit, probes=["out"]).names == ["vm(out)", "vp(out)"]
    with pytest.raises(CircuitInputError, match="no signal nowhere"):
        ac_analysis(circuit, probes=["nowhere"])


def test_cli_writes_the_sweep_as_csv_and_a_bode_plot(tmp_path, capsys):
    path = tmp_path / "rc.cir"
    path.write_text("rc\nV1 in 0 AC 1\nR1 in out 1k\nC1 out 0 1u\n.ac dec 5 10 10k\n.end\n")
    csv, png = tmp_path / "rc.csv", tmp_path / "rc.png"
    assert main(["simulate", str(path), "--csv", str(csv), "--plot", str(png)]) == 0
    assert "16 frequencies" in capsys.readouterr().out
    assert (
        csv.read_text().splitlines()[0] == "frequency,vm(in),vp(in),vm(out),vp(out),im(v1),ip(v1)"
    )
    back = Waveforms.from_csv(csv)
    h = 1 / (1 + 2j * np.pi * back.time * 1e-3)
    assert back.axis == "frequency" and np.allclose(back["vm(out)"], np.abs(h), rtol=1e-14)
    assert png.stat().st_size > 10_000
    scale = tmp_path / "rc.scale.json"
    scale.write_text("{}")
    assert main(["simulate", str(path), "--states", str(scale)]) == 2


# --- against ngspice ------------------------------------------------------------------------


def _ac_deck(path: Path, card: str) -> str:
    """The netlist with ``AC 1`` on its driving source (the first V source with a SIN or PULSE,
    else the first V source) and ``card`` in place of its .tran; other analyses dropped."""
    lines = path.read_text().splitlines()
    sources = [i for i, line in enumerate(lines) if re.match(r"v\w*\s", line, re.I)]
    drive = next((i for i in sources if re.search(r"(sin|pulse)\(", lines[i], re.I)), sources[0])
    lines[drive] += " AC 1"
    out, in_analysis = [], False
    for line in lines:
        word = line.strip().lower().split(" ")[0] if line.strip() else ""
        if word in (".tran", ".op", ".ac", ".print"):  # .print tran needs its .tran
            in_analysis = True
            continue
        if in_analysis and word.startswith("+"):
            continue
        in_analysis = False
        if word == ".end":
            out.append(card)
        out.append(line)
    return "\n".join(out) + "\n"


def _worst(ours: Waveforms, reference: Waveforms) -> tuple[float, float, float]:
    """Worst |dB| and |degrees| difference over the points whose magnitude is above 1e-9 of
    the sweep's largest (below that a phase is rounding), and the worst magnitude difference
    relative to that largest value everywhere."""
    magnitudes = [n for n in reference.names if n.startswith("vm(")]
    big = max(float(reference[n].max()) for n in magnitudes)
    worst_db = worst_deg = worst_abs = 0.0
    for name in magnitudes:
        ref, got = reference[name], ours[name]
        worst_abs = max(worst_abs, float(np.max(np.abs(got - ref))) / big)
        seen = ref > 1e-9 * big
        if not seen.any():
            continue
        worst_db = max(worst_db, float(np.max(np.abs(20 * np.log10(got[seen] / ref[seen])))))
        phase = "vp(" + name[3:]
        turn = (ours[phase] - reference[phase] + 180.0) % 360.0 - 180.0
        worst_deg = max(worst_deg, float(np.max(np.abs(turn[seen]))))
    return worst_db, worst_deg, worst_abs


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize("path", GOLDEN + VENDOR + WHEELSETS, ids=lambda p: p.name)
def test_ac_agrees_with_ngspice(path, tmp_path):
    from circuitsim.interop.ngspice import run_ngspice

    card = ".ac dec 20 0.1 1k" if path.name.startswith("wheelset") else ".ac dec 10 1 1meg"
    deck = tmp_path / path.name
    deck.write_text(_ac_deck(path, card))
    ours = simulate(read_netlist(deck))
    # ngspice 39 takes every voltage-controlled switch as off in .ac (swload.c's
    # MODEINITSMSIG branch copies CKTstate1, which a DC operating point never set): give it
    # the wheelsets' flange switch, closed where its control is 1 V, as its on-resistance
    text = deck.read_text()
    if re.search(r"^VFLANGE_CTL \S+ 0 DC 1$", text, flags=re.M):
        ron = re.search(r"SW_FLANGE SW\(.*ron=(\S+)", text).group(1)
        text = re.sub(r"^S1 (\S+) (\S+) \S+ \S+ SW_FLANGE", rf"RS1 \1 \2 {ron}", text, flags=re.M)
    referee = tmp_path / f"ngspice_{path.name}"
    referee.write_text(text)
    reference = run_ngspice(referee, analysis="ac")
    assert np.allclose(ours.time, reference.time, rtol=1e-13, atol=0.0)
    worst_db, worst_deg, worst_abs = _worst(ours, reference)
    assert worst_db <= 1e-3 and worst_deg <= 0.01, (worst_db, worst_deg)
    assert worst_abs <= 1e-9


@requires_ngspice
@pytest.mark.ngspice
def test_ngspice_39_takes_a_closed_switch_as_open_in_ac(tmp_path):
    """Why the wheelset's referee deck has a resistor for S1 (docs/solver.md says so too)."""
    from circuitsim.interop.ngspice import run_ngspice

    deck = tmp_path / "sw.cir"
    deck.write_text(
        "switch\nV1 a 0 AC 1\nS1 a b c 0 swm\nVc c 0 DC 1\nR1 b 0 1k\n"
        ".model swm SW(vt=0.5 vh=0 ron=10 roff=1meg)\n.ac lin 3 1 10\n.end\n"
    )
    assert np.allclose(run_ngspice(deck)["vm(b)"], 1e3 / (1e3 + 1e6), rtol=1e-9)


@requires_ngspice
@pytest.mark.ngspice
@pytest.mark.parametrize(
    "card", [".ac dec 1000 5 20", ".ac dec 7 3.3 47k", ".ac oct 5 1 100", ".ac lin 7 1 2"]
)
def test_the_frequency_grid_is_ngspice_s_on_awkward_ranges(card):
    from circuitsim.interop.ngspice import run_ngspice

    text = f"rc\nV1 in 0 AC 1\nR1 in out 1k\nC1 out 0 1u\n{card}\n.end\n"
    ours, reference = _run(text).time, run_ngspice(text).time
    assert ours.shape == reference.shape
    assert np.allclose(ours, reference, rtol=1e-15, atol=0.0)


def test_a_decade_sweep_without_a_step_is_refused_before_ngspice_starts():
    """ngspice 39 loops for ever on it (its ratio is infinite); ours gives fstart alone."""
    from circuitsim.interop.ngspice import run_ngspice

    text = "rc\nV1 in 0 AC 1\nR1 in out 1k\nC1 out 0 1u\n.ac dec 3 1 1.5\n.end\n"
    assert _run(text).time.tolist() == [1.0]
    with pytest.raises(CircuitInputError, match="less than one step"):
        run_ngspice(text, timeout=5)
