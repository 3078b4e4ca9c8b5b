"""The parameter sweep: each builtin variant equals its own single run; ngspice and the model
solution as independent references; the CLI verb."""

import csv
import shutil

import numpy as np
import pytest

from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.sweep import run_sweep, sweep_circuits
from circuitsim.compare.values import parse_values
from circuitsim.mechanics import load_model, solve
from circuitsim.netlist.reader import parse_netlist
from circuitsim.netlist.writer import write_netlist
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.synthesis.options import SynthesisOptions

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

VALUES = np.array([50.0, 55.5, 61.0])  # m/s: below, near and above the critical speed
T_STOP = 0.5  # model seconds
WINDOW = 0.2  # model seconds


def wheelset_systems(values):
    model = load_model()
    return [
        model.system(parameters={"V": float(v), "f": 3.0, "a": 0.040}, nonlinear={"flange": True})
        for v in values
    ]


@pytest.fixture(scope="module")
def builtin_sweep():
    systems = wheelset_systems(VALUES)
    options = SynthesisOptions(opamp="ideal", t_stop=T_STOP)
    keep = range(len(VALUES))
    result = run_sweep(
        systems, VALUES, "V", "m/s", "builtin", options, window=WINDOW, workers=2, keep=keep
    )
    return systems, options, result


def test_builtin_sweep_variants_equal_their_single_runs(builtin_sweep):
    """Each variant runs alone (in a worker thread, on the ports kernel): the same time
    points, bit for bit, as simulating its Circuit here with that kernel, and the same values
    to round-off (the sweep forms its one probed unknown row by row, a single run all of them
    column by column); the same for its written and re-read netlist."""
    systems, options, result = builtin_sweep
    variants = sweep_circuits(systems, options)
    assert variants.changed == ["R33", "R44"]
    assert result.stats["kernels"] == ["ports"]
    for k, circuit in enumerate(variants.circuits):
        opts = SimulationOptions.from_circuit(circuit, kernel="ports")
        single = map_waveforms(simulate(circuit, opts), variants.scale_map, ["y"])["y"]
        np.testing.assert_array_equal(result.traces[k][0], single[0])
        span = np.ptp(single[1])
        np.testing.assert_allclose(result.traces[k][1], single[1], rtol=0, atol=1e-12 * span)

        text = parse_netlist(write_netlist(circuit), source=f"variant {k}")
        waves = simulate(text, SimulationOptions.from_circuit(text, kernel="ports"))
        t, y = map_waveforms(waves, variants.scale_map, ["y"])["y"]
        late = t >= t[-1] - WINDOW
        assert result.peak_all[k] == pytest.approx(np.max(np.abs(y)), rel=1e-12, abs=0)
        assert result.peak_late[k] == pytest.approx(np.max(np.abs(y[late])), rel=1e-12, abs=0)


def test_builtin_sweep_agrees_with_the_compiled_kernel(builtin_sweep):
    """The ports kernel's variants against the full compiled kernel (a separate
    implementation of the same step control; measured: peaks within 3.3e-7)."""
    systems, options, result = builtin_sweep
    variants = sweep_circuits(systems, options)
    for k, circuit in enumerate(variants.circuits):
        opts = SimulationOptions.from_circuit(circuit, kernel="compiled")
        t, y = map_waveforms(simulate(circuit, opts), variants.scale_map, ["y"])["y"]
        late = t >= t[-1] - WINDOW
        assert result.peak_all[k] == pytest.approx(np.max(np.abs(y)), rel=1e-4)
        assert result.peak_late[k] == pytest.approx(np.max(np.abs(y[late])), rel=1e-4)


def test_builtin_sweep_peaks_match_the_model_solution(builtin_sweep):
    """Independent reference: the mechanical model's ODE solution (no circuit)."""
    systems, _, result = builtin_sweep
    for k, system in enumerate(systems):
        exact = solve(system, t_span=(0.0, T_STOP)).max_abs("y")
        assert result.peak_all[k] == pytest.approx(exact, rel=0.02)


@requires_ngspice
def test_ngspice_sweep_agrees_with_builtin(builtin_sweep):
    systems, options, ours = builtin_sweep
    theirs = run_sweep(systems, VALUES, "V", "m/s", "ngspice", options, window=WINDOW, workers=2)
    assert theirs.stats["processes"] == len(VALUES)
    # the builtin engine's kernels are made ready outside the simulation's time; ngspice has none
    assert ours.timings["kernels"] > 0 and "kernels" not in theirs.timings
    np.testing.assert_allclose(ours.peak_all, theirs.peak_all, rtol=1e-3)
    np.testing.assert_allclose(ours.peak_late, theirs.peak_late, rtol=1e-3)


def test_sweep_cli_writes_csv_and_plot(tmp_path, capsys):
    from circuitsim.cli import main

    out = tmp_path / "sweep"
    argv = ["sweep", "--param", "speed", "--values", "50,60", "--tstop", "0.1", "--out", str(out)]
    assert main([*argv, "--jobs", "2"]) == 0
    assert "compiled kernels ready" in capsys.readouterr().out
    assert (out / "sweep.png").stat().st_size > 1000
    with open(out / "sweep.csv") as handle:
        rows = list(csv.reader(handle))
    assert rows[0][0].startswith("V")
    assert [float(r[0]) for r in rows[1:]] == [50.0, 60.0]
    # the resistors the speed turns, per row: proportional to V (c = 7.24e6 / V sets 1 / R33)
    assert rows[0][3:] == ["R33 (ohm)", "R44 (ohm)"]
    for column in (3, 4):
        assert float(rows[2][column]) / float(rows[1][column]) == pytest.approx(1.2, rel=1e-12)
    model = load_model()
    for row in rows[1:]:
        system = model.system(parameters={"V": float(row[0])}, nonlinear={"flange": True})
        exact = solve(system, t_span=(0.0, 0.1)).max_abs("y")
        assert float(row[2]) == pytest.approx(exact, rel=0.02)


def test_sweep_values_grid_includes_stop():
    values = parse_values("40:70:0.5")
    assert values.size == 61 and values[0] == 40.0 and values[-1] == pytest.approx(70.0)
    assert list(parse_values("1, 2.5,4")) == [1.0, 2.5, 4.0]


@pytest.mark.parametrize(
    "argv",
    [
        ["--param", "speed", "--values", "5:1:1"],
        ["--param", "speed", "--param", "freq", "--values", "1:2:1"],
        ["--param", "no_such_parameter", "--values", "1:2:1"],
        ["--param", "speed", "--values", "50,60", "--jobs", "0"],
    ],
    ids=["empty-range", "two-swept", "unknown", "no-jobs"],
)
def test_sweep_cli_refuses_bad_input(argv, tmp_path, capsys):
    from circuitsim.cli import main

    assert main(["sweep", *argv, "--out", str(tmp_path)]) == 2
    assert "error" in capsys.readouterr().err
    assert not (tmp_path / "sweep.csv").exists()


def test_a_tl074_sweep_warns_where_a_state_reached_the_swing():
    """Every state node is probed for op-amps with a finite swing: a scaling that would put
    psi at about 4 x 5 V makes the TL074 circuit clip at 12.9 V (warned, with the values); the
    sweep's own scaling does not; ideal op-amps have no swing to check. (psi, not y: y's scale
    is lowered for the flange's |x| blocks, whose offsets must stay within the swing.)"""
    from circuitsim.synthesis.scaling import direct_solution

    systems = wheelset_systems(VALUES)
    _, x = direct_solution(systems[1], T_STOP)
    peaks = dict(zip(systems[1].states, np.max(np.abs(x), axis=1), strict=True))
    tight = {**peaks, "psi": peaks["psi"] / 4}
    runs = {}
    for label, opamp, ranges in (
        ("tight", "tl074", tight),
        ("own", "tl074", {}),
        ("ideal", "ideal", tight),
    ):
        options = SynthesisOptions(opamp=opamp, t_stop=T_STOP, ranges=ranges)
        runs[label] = run_sweep(systems, VALUES, "V", "m/s", "builtin", options, workers=2)
    (warning,) = runs["tight"].warnings
    assert warning.startswith(
        "state psi (psi) reached the tl074 op-amp's output swing (about 13 V) in 3 of 3 variants "
        "(V 50 to 61 m/s; "
    )
    volts = float(warning.split("m/s; ")[1].split(" V at")[0])
    assert 0.95 * 13.0 <= volts < 15.0  # at the swing (the clip check's threshold), not beyond
    assert runs["own"].warnings == []
    assert runs["ideal"].warnings == []


def test_sweep_scaling_solves_each_probe_once(monkeypatch):
    """The shared scaling needs the direct solutions of the first, middle and last values;
    the middle one serves the base synthesis as well (three solutions in all), which gives
    the circuit of synthesizing the middle value alone at the sweep's ranges."""
    import circuitsim.compare.sweep as sweep_module
    import circuitsim.synthesis.translator as translator
    from circuitsim.synthesis.scaling import direct_solution

    systems = wheelset_systems([50.0, 52.0, 55.5, 58.0, 61.0])
    options = SynthesisOptions(opamp="ideal", t_stop=T_STOP)
    calls = []

    def counted(system, t_stop):
        calls.append(system)
        return direct_solution(system, t_stop)

    monkeypatch.setattr(sweep_module, "direct_solution", counted)
    monkeypatch.setattr(translator, "direct_solution", counted)
    variants = sweep_circuits(systems, options)
    assert calls == [systems[0], systems[2], systems[-1]]

    monkeypatch.undo()
    alone = translator.synthesize(
        systems[2], SynthesisOptions(opamp="ideal", t_stop=T_STOP, series="exact",
                                     ranges=variants.ranges)
    )  # fmt: skip
    assert write_netlist(variants.circuits[2]) == write_netlist(alone.circuit)


def test_sweep_csv_reads_back_exactly_in_shortest_form():
    from circuitsim.compare.sweep import SweepResult

    values = parse_values("0.1:0.3:0.1")  # 0.1 + 0.1 * 2 is 0.30000000000000004
    peaks = np.array([1e-3 / 3, 2.5e-3, 0.005])
    result = SweepResult("k", "", values, "u", "V", peaks, 2 * peaks, "builtin", 0.5)
    lines = result.csv_text().splitlines()
    assert lines[0] == "k,max_abs_u_last_0.5s (V),max_abs_u_all (V)"
    assert lines[1] == "0.1,0.0003333333333333333,0.0006666666666666666"
    assert lines[3].split(",")[2] == "0.01"
    table = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    np.testing.assert_array_equal(table, np.column_stack([values, peaks, 2 * peaks]))
