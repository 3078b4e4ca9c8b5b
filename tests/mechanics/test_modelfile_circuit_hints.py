"""The ``[circuit]`` hints are checked when the model file is read: a bad ``t_stop`` is a
ModelError naming the file and ``circuit.t_stop``, not a broken netlist line, and part names
must be strings keyed by parts of the model."""

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


@pytest.mark.parametrize(
    ("hints", "key", "message"),
    [
        ('integrators = { y = "U1A" }', "circuit.integrators.y", "not a state of the model"),
        ("capacitors = { x = 5 }", "circuit.capacitors.x", "expected a part name, got int"),
        ('switches = { flange = "S1" }', "circuit.switches.flange", "not a nonlinear term"),
        ('sources = { track = "XFG1" }', "circuit.sources.track", "not a forcing term"),
        ('resistors = { x_dot = { z = "R1" } }', "circuit.resistors.x_dot.z", "not a state, term"),
        ('resistors = { z = { x = "R1" } }', "circuit.resistors.z", "not a state of the model"),
        ('speed = { parameter = "Vq" }', "circuit.speed.parameter", "unknown parameter 'Vq'"),
        ('speed = { parameter = "k", entries = [["x", "q"]] }', "circuit.speed.entries", "pairs"),
    ],
)
def test_part_name_hints_must_name_parts_of_the_model(tmp_path, hints, key, message):
    """A hint keyed by nothing of the model would be dropped (or a number made a part name)
    without a word: the file and the key are named instead."""
    with pytest.raises(ModelError, match=message) as caught:
        load_model(write(tmp_path, hints))
    assert caught.value.key == key


def test_part_name_hints_of_the_model_are_kept(tmp_path):
    hints = (
        'capacitors = { x = "C9", x_dot = "C8" }\n'
        'speed = { parameter = "k", entries = [["x_dot", "x"]] }'
    )
    assert load_model(write(tmp_path, hints)).system().circuit_hints["capacitors"]["x"] == "C9"
