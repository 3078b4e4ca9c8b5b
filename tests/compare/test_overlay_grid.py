"""The circuit-over-ODE overlay for many states: a grid of columns past six states, the
states the user picks (``compare --states``), the model's time unit on the time axis."""

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.compare.plots import plot_overlay


def traces(names):
    t = np.linspace(0.0, 1.0, 200)
    reference = {n: (t, np.sin((k + 1) * t)) for k, n in enumerate(names)}
    circuit = {n: (t, v + 1e-3) for n, (t, v) in reference.items()}
    return reference, {"builtin": circuit}


def visible(figure):
    return [a for a in figure.axes if a.get_visible()]


def test_thirty_states_make_a_grid_not_one_column(tmp_path):
    names = [f"q{k}" for k in range(30)]
    reference, circuits = traces(names)
    figure = plot_overlay(tmp_path / "all.png", reference, circuits, errors=True)
    width, height = figure.get_size_inches() * 72
    assert height < 1300 and width / height > 1.0  # one column would be 460 x 6500 px
    drawn = [a for a in visible(figure) if a.get_ylabel() in names]
    drawn.sort(key=lambda a: (round(a.get_position().x0, 3), -a.get_position().y0))
    assert [a.get_ylabel() for a in drawn] == names  # column by column, in order
    columns = {round(a.get_position().x0, 3) for a in drawn}
    assert len(columns) == 5
    assert len(visible(figure)) == 60  # each state with its error panel
    assert (tmp_path / "all.png").stat().st_size > 1000


def test_the_states_picked_in_their_order_and_a_dimensionless_time(tmp_path):
    reference, circuits = traces(["a", "b", "c"])
    figure = plot_overlay(
        tmp_path / "two.png", reference, circuits, states=["c", "a"], time_unit=""
    )
    assert [a.get_ylabel() for a in visible(figure)] == ["c", "a"]
    assert visible(figure)[-1].get_xlabel() == "model time (dimensionless)"
    seven = plot_overlay(tmp_path / "seven.png", *traces(list("abcdefg")), time_unit="s")
    bottoms = [a for a in visible(seven) if a.get_xlabel()]
    assert len(bottoms) == 2 and all(a.get_xlabel() == "model time (s)" for a in bottoms)
    assert sum(not a.get_visible() for a in seven.axes) == 1  # the second column's 8th slot


def test_compare_plots_the_states_named(tmp_path, capsys):
    plot = tmp_path / "c.png"
    args = ["compare", "--tstop", "0.5", "--plot", str(plot), "--states", "psi,y"]
    assert main(args) == 0
    assert plot.stat().st_size > 1000
    assert main(["compare", "--tstop", "0.5", "--plot", str(plot), "--states", "y,q"]) == 2
    assert "--states: no state 'q' in model wheelset" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["compare", "--states", "y,,psi"])
    assert exit_info.value.code == 2
