"""Parameter grids: the full product, CSV sets and their errors, a grid run against single runs
and the direct solution, the tidy CSV and the map; the sweep verb's grid options."""

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from circuitsim.compare.mapping import map_waveforms
from circuitsim.compare.sweep import sweep_circuits
from circuitsim.mechanics import load_model, solve
from circuitsim.solver import SimulationOptions, simulate
from circuitsim.studies.errors import GridFileError, StudyError
from circuitsim.studies.grid import full_grid, read_grid_csv
from circuitsim.studies.study import run_grid, save_grid
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import synthesize

ROOT = Path(__file__).resolve().parents[2]
T_STOP = 0.5  # model seconds
WINDOW = 0.2
UNITS = {"V": "m/s", "lambda": "1", "a": "m"}


def resolve(label):
    name = {"speed": "V"}.get(label, label)
    if name not in UNITS:
        raise KeyError(f"no parameter {label!r}")
    return name, UNITS[name]


def grid_systems(grid, **fixed):
    model = load_model()
    return [
        model.system("derived", {**fixed, **dict(grid.assignments(k))}, {"flange": True})
        for k in range(len(grid))
    ]


def test_a_full_grid_is_the_product_with_the_last_parameter_fastest():
    axes = [np.array([50.0, 60.0]), np.array([0.1, 0.2, 0.3])]
    grid = full_grid(["V", "lambda"], ["m/s", "1"], axes)
    assert grid.shape == (2, 3)
    assert grid.points.tolist() == [
        [50, 0.1], [50, 0.2], [50, 0.3], [60, 0.1], [60, 0.2], [60, 0.3],
    ]  # fmt: skip
    assert grid.describe(4) == "V 60 m/s, lambda 0.2 1"
    with pytest.raises(StudyError, match="100 x 101 = 10,100 variants, more than 10,000"):
        full_grid(["V", "a"], ["m/s", "m"], [np.arange(100.0), np.arange(101.0)])
    with pytest.raises(StudyError, match="parameter V is named twice"):
        full_grid(["V", "V"], ["m/s", "m/s"], [np.ones(2), np.ones(2)])


def test_grid_csv_sets_with_comments_units_and_option_names(tmp_path):
    path = tmp_path / "sets.csv"
    path.write_text("# a study\n\nspeed (m/s), lambda\n50, 0.1\n# skipped\n55.5,0.25\n")
    grid = read_grid_csv(path, resolve)
    assert grid.names == ("V", "lambda") and grid.units == ("m/s", "1")
    assert grid.points.tolist() == [[50.0, 0.1], [55.5, 0.25]]
    assert grid.axes is None and grid.source == str(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "no header line"),
        ("V,lambda\n", "no parameter sets after the header (line 1)"),
        ("V,mass\n50,1\n", "line 1, column 2: no parameter 'mass'"),
        ("V (km/h)\n50\n", "line 1, column 1 (V): unit 'km/h', but V is in m/s"),
        ("V,speed\n50,50\n", "line 1, column 2 (speed): parameter V is already column 1"),
        ("V,lambda\n50,0.1\n55,abc\n", "line 3, column 2 (lambda): 'abc' is not a number"),
        ("V,lambda\n50,0.1\n55,nan\n", "line 3, column 2 (lambda): nan is not a finite number"),
        ("V,lambda\n50,0.1\n55\n", "line 3: 1 values, expected 2 (V, lambda)"),
        ("(m/s)\n50\n", "line 1, column 1: expected a parameter name, got '(m/s)'"),
    ],
)
def test_grid_csv_errors_name_file_line_and_column(tmp_path, text, message):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(GridFileError) as caught:
        read_grid_csv(path, resolve)
    assert str(caught.value) == f"{path}: {message}" or str(caught.value).startswith(
        f"{path}: {message}"
    )


def test_grid_csv_row_limit_and_unreadable_file(tmp_path):
    path = tmp_path / "many.csv"
    path.write_text("V\n" + "50\n" * 4)
    with pytest.raises(GridFileError, match="4 parameter sets, more than 3"):
        read_grid_csv(path, resolve, limit=3)
    with pytest.raises(GridFileError, match="cannot read the grid file"):
        read_grid_csv(tmp_path / "missing.csv", resolve)


def test_conicity_variants_rescale_the_forcing_resistor_as_the_translator_sets_it():
    """Conicity changes k_y, which the track input enters with: a variant's forcing resistor
    is the base's rescaled, and equals (to round-off) the one the translator gives that
    variant's system with the same scaling."""
    grid = full_grid(["lambda"], ["1"], [np.array([0.1, 0.3, 0.45])])
    systems = grid_systems(grid, V=55.0, a=0.004)
    options = SynthesisOptions(t_stop=T_STOP)
    variants = sweep_circuits(systems, options)
    assert variants.rescaled
    assert variants.changed == ["R31", "R17", "R41", "R42"]  # R17: the track input's
    exact = SynthesisOptions(t_stop=T_STOP, series="exact", ranges=variants.ranges)
    for system, circuit in zip(systems, variants.circuits, strict=True):
        alone = synthesize(system, exact, peaks=False).circuit
        for name in variants.changed:
            ours, theirs = circuit.element(name), alone.element(name)
            # the translator writes 12 significant digits
            assert ours.resistance == pytest.approx(theirs.resistance, rel=1e-11), name


@pytest.fixture(scope="module")
def speed_conicity_grid():
    grid = full_grid(["V", "lambda"], ["m/s", "1"], [np.array([50.0, 60.0]), np.array([0.2, 0.35])])
    systems = grid_systems(grid, a=0.0, y0=0.005)
    options = SynthesisOptions(t_stop=T_STOP)
    result = run_grid(systems, grid, options=options, window=WINDOW, workers=2)
    return grid, systems, options, result


def test_grid_variants_equal_their_single_runs_and_the_direct_solution(speed_conicity_grid):
    grid, systems, options, result = speed_conicity_grid
    sweep = result.sweep
    assert sweep.stats["shared_start"] == len(grid)  # resistor changes only
    variants = sweep_circuits(systems, options)
    for k, (system, circuit) in enumerate(zip(systems, variants.circuits, strict=True)):
        waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
        t, y = map_waveforms(waves, variants.scale_map, ["y"])["y"]
        late = t >= t[-1] - WINDOW
        assert sweep.peak_all[k] == pytest.approx(np.max(np.abs(y)), rel=1e-12, abs=1e-15)
        assert sweep.peak_late[k] == pytest.approx(np.max(np.abs(y[late])), rel=1e-9, abs=1e-15)
        exact = solve(system, t_span=(0.0, T_STOP)).max_abs("y")
        assert sweep.peak_all[k] == pytest.approx(exact, rel=2e-3)


def test_tidy_csv_and_map(speed_conicity_grid, tmp_path):
    grid, _, _, result = speed_conicity_grid
    paths = save_grid(result, tmp_path)
    assert [p.name for p in paths] == ["sweep.csv", "sweep.png"]
    rows = list(csv.DictReader(paths[0].open()))
    assert list(rows[0]) == ["variant", "V (m/s)", "lambda (1)", "metric", "value", "unit"]
    assert len(rows) == 2 * len(grid)
    late = [r for r in rows if r["metric"] == f"max_abs_y_last_{WINDOW:g}s"]
    assert [float(r["value"]) for r in late] == result.sweep.peak_late.tolist()
    assert [(float(r["V (m/s)"]), float(r["lambda (1)"])) for r in late] == [
        tuple(p) for p in grid.points.tolist()
    ]
    assert paths[1].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def run_cli(*args, cwd):
    return subprocess.run(
        [sys.executable, "-m", "circuitsim", "sweep", *args],
        cwd=cwd,
        env={**__import__("os").environ, "PYTHONPATH": str(ROOT)},
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_sweep_verb_grid_errors_are_one_line_with_exit_2(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("speed,lambda\n50,0.2\n55,x\n")
    common = ("--coeffs", "derived", "--tstop", "0.1", "--out", str(tmp_path / "o"))
    cases = [
        (("--grid", str(bad)), f"{bad}: line 3, column 2 (lambda): 'x' is not a number"),
        (("--param", "speed", "--values", "50,60", "--param", "lambda"),
         "2 swept --param NAME and 1 --values"),
        (("--param", "speed", "--values", "50", "--scheduler", "local", "--engine", "ngspice"),
         "--scheduler runs the builtin engine only"),
        (("--param", "speed", "--values", "50", "--scheduler", "local:0"),
         "expected local or local:N with N >= 1"),
        (("--grid", str(bad), "--param", "speed", "--values", "50"),
         "--grid FILE gives the parameter sets"),
        (("--param", "speed", "--values", "50", "--param", "lambda", "--values", "0.1",
          "--param", "lambda=0.2"), "--param lambda=0.2 fixes lambda, which --param lambda"),
    ]  # fmt: skip
    for args, message in cases:
        out = run_cli(*args, *common, cwd=tmp_path)
        assert out.returncode == 2, (args, out.stderr)
        assert message in out.stderr, (args, out.stderr)
        assert "Traceback" not in out.stderr


@pytest.mark.slow
def test_sweep_verb_two_parameter_grid_writes_tidy_csv_and_map(tmp_path):
    out = run_cli(
        "--coeffs", "derived", "--param", "speed", "--values", "50,60", "--param", "lambda",
        "--values", "0.2,0.35", "--amplitude", "0", "--y0", "0.005", "--tstop", "0.5",
        "--window", "0.2", "--out", str(tmp_path), cwd=tmp_path,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "2 x 2 = 4 variants of V, lambda (builtin, in-process" in out.stdout
    assert "4 from the base circuit's shared start" in out.stdout
    rows = list(csv.DictReader((tmp_path / "sweep.csv").open()))
    assert len(rows) == 8
    assert (tmp_path / "sweep.png").stat().st_size > 0


def test_variants_whose_capacitors_differ_are_assembled_on_their_own():
    """The initial displacement sets the y integrator's capacitor's initial voltage: such
    variants cannot run from the base circuit's shared start (resistor changes only); they
    are assembled on their own, counted apart, and still equal their single runs."""
    grid = full_grid(["V", "y0"], ["m/s", "m"], [np.array([50.0, 60.0]), np.array([3e-3, 5e-3])])
    model = load_model()
    systems = [
        model.system(parameters={"a": 0.0, **dict(grid.assignments(k))}) for k in range(len(grid))
    ]
    options = SynthesisOptions(t_stop=0.3)
    result = run_grid(systems, grid, options=options, window=0.1, workers=2)
    variants = sweep_circuits(systems, options)
    base = variants.circuits[len(grid) // 2]  # V 60, y0 3 mm
    assert not variants.rescaled and "C1" in variants.changed
    # the base's y0 (V 50 differs from it in resistors only) from the shared start; the other
    # y0's two variants (their C1 starts elsewhere) assembled on their own
    assert result.sweep.stats["shared_start"] == 2
    for k, circuit in enumerate(variants.circuits):
        same_ic = circuit.element("C1") == base.element("C1")
        assert same_ic == (grid.points[k, 1] == 3e-3)
        waves = simulate(circuit, SimulationOptions.from_circuit(circuit, kernel="ports"))
        t, y = map_waveforms(waves, variants.scale_map, ["y"])["y"]
        assert result.sweep.peak_all[k] == pytest.approx(np.max(np.abs(y)), rel=1e-12)
        exact = solve(systems[k], t_span=(0.0, 0.3)).max_abs("y")
        assert result.sweep.peak_all[k] == pytest.approx(exact, rel=2e-3)


def test_progress_messages_give_the_time_left():
    from circuitsim.compare.sweep_measure import Eta

    eta = Eta("dask, 2 workers")
    eta.started -= 10.0  # ten seconds ago
    assert eta.message(0, 100) == "dask, 2 workers: 0 of 100 variants"
    assert eta.message(25, 100) == "dask, 2 workers: 25 of 100 variants, 30 s left"
    assert eta.message(100, 100) == "dask, 2 workers: 100 of 100 variants"
    eta.started -= 990.0
    assert eta.message(10, 100).endswith("2.5 h left")


def test_an_entry_that_is_zero_in_the_base_is_not_lost_in_the_other_variants():
    """Conicity 0 makes k_psiy 0: the base circuit (the middle variant, lambda 0) has no R41.
    The other variants need it: they are translated on their own (not the base rescaled,
    which would silently run them with k_psiy = 0), and match their direct solutions."""
    grid = full_grid(["lambda"], ["1"], [np.array([0.3, 0.0, 0.45])])
    systems = grid_systems(grid, V=58.0, a=0.0, y0=0.005)
    result = run_grid(systems, grid, options=SynthesisOptions(t_stop=T_STOP), window=WINDOW)
    assert "R41" in result.sweep.changed
    assert result.sweep.stats["shared_start"] == 1  # the base alone
    for k, system in enumerate(systems):
        exact = solve(system, t_span=(0.0, T_STOP))
        assert result.sweep.peak_all[k] == pytest.approx(exact.max_abs("y"), rel=2e-3)
        late = exact.max_abs("y", t_from=T_STOP - WINDOW)
        # a decayed late peak (nanometres at lambda 0): within 0.1 % of the run's range
        scale = 1e-3 * exact.max_abs("y")
        assert result.sweep.peak_late[k] == pytest.approx(late, rel=2e-3, abs=scale)
