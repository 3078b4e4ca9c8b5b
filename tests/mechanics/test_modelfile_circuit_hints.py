"""The ``[circuit]`` hints that are numbers are checked when the model file is read: a bad
``t_stop`` is a ModelError naming the file and ``circuit.t_stop``, not a broken netlist line."""

import textwrap

import pytest

from circuitsim.mechanics import ModelError, load_model

SPRING = """
[model]
name = "spring"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
m = 2.0
k = 50.0

[matrices]
M = [["m"]]
K = [["k"]]

[circuit]
"""


def write(tmp_path, circuit_lines: str):
    path = tmp_path / "spring.toml"
    path.write_text(textwrap.dedent(SPRING) + circuit_lines + "\n")
    return path


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("t_stop = -5.0", "must be a positive number of seconds, got -5.0"),
        ("t_stop = 0", "must be a positive number of seconds, got 0"),
        ("t_stop = inf", "must be a positive number of seconds, got inf"),
        ("t_stop = nan", "must be a positive number of seconds, got nan"),
        ('t_stop = "5"', "wrong type: expected a number of seconds, got a string"),
        ("t_stop = true", "wrong type: expected a number of seconds, got a boolean"),
    ],
)
def test_a_bad_t_stop_names_file_and_key(tmp_path, line, message):
    path = write(tmp_path, line)
    with pytest.raises(ModelError) as caught:
        load_model(path)
    assert caught.value.file == str(path)
    assert caught.value.key == "circuit.t_stop"
    assert str(caught.value) == f"{path}: circuit.t_stop: {message}"


@pytest.mark.parametrize(("line", "seconds"), [("t_stop = 2.5", 2.5), ("t_stop = 3", 3)])
def test_a_good_t_stop_reaches_the_translator(tmp_path, line, seconds):
    system = load_model(write(tmp_path, line)).system()
    assert system.circuit_hints["t_stop"] == seconds


def test_other_hints_stay_free_form(tmp_path):
    path = write(tmp_path, 'capacitors = { x = "C9" }\nanything = [1, "two"]')
    hints = load_model(path).system().circuit_hints
    assert hints == {"capacitors": {"x": "C9"}, "anything": [1, "two"]}
