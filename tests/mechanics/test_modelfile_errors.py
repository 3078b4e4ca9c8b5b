"""Every kind of model-file mistake gives a ModelError naming the file, the key and the fault."""

import re
import textwrap

import pytest

from circuitsim.mechanics import ModelError, load_model

GOOD = """
[model]
name = "spring"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
m = 2.0
k = { value = 50.0, unit = "N/m" }

[matrices]
M = [["m"]]
K = [["k"]]
"""


def load_text(tmp_path, text):
    path = tmp_path / "bad.toml"
    path.write_text(textwrap.dedent(text))
    return load_model(path), path


def error_for(tmp_path, text) -> tuple[ModelError, str]:
    path = tmp_path / "bad.toml"
    path.write_text(textwrap.dedent(text))
    with pytest.raises(ModelError) as caught:
        load_model(path)
    return caught.value, str(path)


def test_the_good_file_loads(tmp_path):
    model, _ = load_text(tmp_path, GOOD)
    assert model.states == ("x", "x_dot")
    assert model.units == ("m", "m/s")
    assert model.parameter_info["k"].unit == "N/m"


CASES = [
    # (edit of GOOD, key, words in the message)
    (lambda s: s + "\n[extra]\n", "extra", "unknown key"),
    (lambda s: s.replace('kind = "second_order"\n', ""), "model.kind", "missing key"),
    (lambda s: s.replace('"second_order"', '"third_order"'), "model.kind", "must be one of"),
    (lambda s: s.replace("m = 2.0", 'm = "two"'), "parameters.m", "unknown name 'two'"),
    (lambda s: s.replace("m = 2.0", "m = [2.0]"), "parameters.m", "wrong type"),
    (
        lambda s: s.replace("value = 50.0, unit", "value = true, unit"),
        "parameters.k.value",
        "wrong type",
    ),
    (lambda s: s.replace('K = [["k"]]', 'K = [["k * / 2"]]'), "matrices.K[0][0]", "bad expression"),
    (lambda s: s.replace('K = [["k"]]', 'K = [["k ^ 2"]]'), "matrices.K[0][0]", "use \\*\\*"),
    (lambda s: s.replace('K = [["k"]]', 'K = [["kk"]]'), "matrices.K[0][0]", "unknown name 'kk'"),
    (
        lambda s: s.replace('K = [["k"]]', 'K = [["sqrt(k, 2)"]]'),
        "matrices.K[0][0]",
        "takes 1 argument",
    ),
    (
        lambda s: s.replace('K = [["k"]]', 'K = [["frobnicate(k)"]]'),
        "matrices.K[0][0]",
        "unknown function",
    ),
    (
        lambda s: s.replace('K = [["k"]]', 'K = [["k / (m - 2)"]]'),
        "matrices.K[0][0]",
        "division by zero",
    ),
    (lambda s: s.replace('M = [["m"]]', 'M = [["m - 2"]]'), "matrices.M", "singular mass"),
    (lambda s: s.replace('M = [["m"]]', 'M = [["m", 0]]'), "matrices.M[0]", "wrong row length"),
    (lambda s: s.replace('M = [["m"]]', 'M = [["m"], [0]]'), "matrices.M", "wrong number of rows"),
    (lambda s: s.replace('M = [["m"]]\n', ""), "matrices.M", "missing key"),
    (lambda s: s.replace('M = [["m"]]', 'M = "m"'), "matrices.M", "wrong type"),
    (lambda s: s.replace('M = [["m"]]', 'M = [["m"]]\nA = [[1]]'), "matrices.A", "unknown key"),
    (
        lambda s: s.replace('units = ["m"]', 'units = ["m", "s"]'),
        "coordinates.units",
        "wrong length",
    ),
    (lambda s: s.replace('names = ["x"]', 'names = ["x", "x"]'), "coordinates.names", "duplicate"),
    (
        lambda s: s.replace('names = ["x"]', 'names = ["2x"]'),
        "coordinates.names",
        "not a valid name",
    ),
    (lambda s: s.replace("m = 2.0", "m = 2.0\nsqrt = 1.0"), "parameters.sqrt", "reserved"),
    (
        lambda s: s + '\n[coefficients]\ndefault = "nope"\n[coefficients.a]\nc = 1\n',
        "coefficients.default",
        "unknown set 'nope'",
    ),
    (lambda s: s + "\n[coefficients]\nset = 3\n", "coefficients.set", "wrong type"),
    (lambda s: s + "\n[coefficients.a]\nm = 1\n", "coefficients.a.m", "reuse a parameter"),
    (lambda s: s + '\n[options]\nspeed = "V"\n', "options.speed", "unknown parameter 'V'"),
    (lambda s: s + "\n[initial]\nz = 1\n", "initial.z", "unknown name"),
    (lambda s: s + '\n[initial]\nx = "q"\n', "initial.x", "unknown name 'q'"),
    (
        lambda s: s + '\n[nonlinear.gap]\nlinear = { x = "k" }\n',
        "nonlinear.gap.enters",
        "missing key",
    ),
    (
        lambda s: s + "\n[nonlinear.gap]\nenters = { x = 1 }\nabs = [{ gain = 1 }]\n",
        "nonlinear.gap.abs[0].row",
        "missing key",
    ),
    (
        lambda s: (
            s + "\n[nonlinear.gap]\nenters = { x = 1 }\nabs = [{ gain = 1, row = [1, 0, 0] }]\n"
        ),
        "nonlinear.gap.abs[0].row",
        "wrong row length",
    ),
    (
        lambda s: s + '\n[nonlinear.gap]\nenters = { x = 1 }\nenabled = "yes"\n',
        "nonlinear.gap.enabled",
        "wrong type",
    ),
    (
        lambda s: s + "\n[nonlinear.gap]\nenters = { x = 1 }\ngian = 1\n",
        "nonlinear.gap.gian",
        "unknown key",
    ),
    (
        lambda s: s + "\n[forcing.push]\namplitude = 1\nenters = { x = 1 }\n",
        "forcing.push.frequency",
        "missing key",
    ),
    (
        lambda s: s + "\n[forcing.push]\namplitude = 1\nfrequency = 2\nenters = { y = 1 }\n",
        "forcing.push.enters.y",
        "unknown name",
    ),
    (lambda s: s + "\n[circuit]\n", None, None),  # an empty circuit table is fine
]


@pytest.mark.parametrize(("edit", "key", "words"), CASES)
def test_model_file_error_names_file_key_and_fault(tmp_path, edit, key, words):
    text = edit(textwrap.dedent(GOOD))
    if key is None:
        load_text(tmp_path, text)
        return
    error, path = error_for(tmp_path, text)
    assert error.file == path
    assert error.key == key
    assert re.search(words, error.message)
    assert str(error).startswith(f"{path}: {key}: ")


def test_not_toml(tmp_path):
    error, path = error_for(tmp_path, "[model\nname = 1")
    assert error.file == path and "not valid TOML" in error.message


def test_missing_file(tmp_path):
    with pytest.raises(ModelError, match="model file not found") as caught:
        load_model(tmp_path / "absent.toml")
    assert caught.value.file.endswith("absent.toml")


def test_first_order_needs_states_not_coordinates(tmp_path):
    text = GOOD.replace('"second_order"', '"first_order"')
    error, _ = error_for(tmp_path, text)
    assert error.key == "coordinates" and "first_order" in error.message


def test_system_rejects_unknown_parameter_set_term_and_state(tmp_path):
    text = GOOD + '\n[nonlinear.gap]\nenters = { x = 1 }\nlinear = { x = "k" }\n'
    model, path = load_text(tmp_path, text)
    with pytest.raises(ModelError, match="unknown parameter") as caught:
        model.system(parameters={"V": 3})
    assert caught.value.key == "parameters.V" and caught.value.file == str(path)
    with pytest.raises(ModelError, match="unknown coefficient set 'paper'"):
        model.system(coefficients="paper")
    with pytest.raises(ModelError, match="unknown nonlinear term"):
        model.system(nonlinear={"flange": True})
    with pytest.raises(ModelError, match="unknown state"):
        model.system(x0={"y": 1.0})
    with pytest.raises(ModelError, match="x0 needs 2 values"):
        model.system(x0=[1.0, 2.0, 3.0])
    with pytest.raises(ModelError, match="expected a number"):
        model.system(parameters={"k": "stiff"})
    # a parameter value that makes the mass matrix singular is caught at system() time too
    with pytest.raises(ModelError, match="singular mass matrix"):
        model.system(parameters={"m": 0.0})


def test_wheelset_system_errors_name_the_builtin_file():
    model = load_model()
    with pytest.raises(ModelError) as caught:
        model.system(parameters={"V": 0.0})
    assert caught.value.file.endswith("wheelset.toml")
    assert caught.value.key == "coefficients.paper.c_y"
    assert "division by zero" in caught.value.message
