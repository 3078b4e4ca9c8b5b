"""Parameters as expressions of other parameters, and the errors of the model language."""

import math

import pytest

from circuitsim.mechanics import ModelError, load_model
from circuitsim.mechanics.modelfile import builtin_path, model_path, shipped_models

BASE = """
[model]
name = "oscillator"
kind = "second_order"

[coordinates]
names = ["x"]
units = ["m"]

[parameters]
{parameters}

[matrices]
M = [["m"]]
K = [["k"]]
"""


def write(tmp_path, parameters: str, extra: str = ""):
    path = tmp_path / "model.toml"
    path.write_text(BASE.format(parameters=parameters) + extra)
    return path


def test_parameters_in_any_order_evaluate_in_dependency_order(tmp_path):
    # the wheelset's Table 1 stiffness written as parameters; k before the names it uses
    path = write(
        tmp_path,
        'k = "2*Ky + W*lambda/b"\nm0 = "-8/7"\nm = { value = "1500", unit = "kg" }\n'
        "Ky = 2.4e6\nW = 21600.0\nlambda = 0.3\nb = 0.74",
    )
    model = load_model(path)
    assert model.parameters["k"] == 2 * 2.4e6 + 21600 * 0.3 / 0.74
    assert model.parameters["m0"] == -8 / 7
    assert model.parameter_info["m"].unit == "kg" and model.parameters["m"] == 1500.0
    system = model.system()
    assert system.A[1, 0] == pytest.approx(-(2 * 2.4e6 + 21600 * 0.3 / 0.74) / 1500, rel=1e-15)


def test_a_given_value_replaces_the_expression_and_its_dependents_follow(tmp_path):
    path = write(tmp_path, 'm = 2.0\nwn = "2*pi*f"\nf = 3.0\nk = "m*wn**2"')
    model = load_model(path)
    omega = 2 * math.pi * 5.0
    system = model.system(parameters={"f": 5.0})
    assert system.parameters["wn"] == pytest.approx(omega, rel=1e-15)
    assert system.A[1, 0] == pytest.approx(-(omega**2), rel=1e-14)
    # setting the derived parameter itself fixes it, whatever f says
    assert model.system(parameters={"wn": 10.0, "f": 7.0}).A[1, 0] == pytest.approx(-100.0)


@pytest.mark.parametrize(
    ("parameters", "key", "words"),
    [
        ('m = 1.0\nk = "2*q"', "parameters.k", "unknown name 'q'"),
        ('m = 1.0\nk = "x"', "parameters.k", "unknown name 'x'"),  # a state is not a parameter
        ('m = 1.0\nk = "a"\na = "2*b"\nb = "k + 1"', "parameters.k", "cycle in parameter "
         "expressions: k -> a -> b -> k"),  # fmt: skip
        ('m = 1.0\nk = "k + 1"', "parameters.k", "cycle in parameter expressions: k -> k"),
        ('m = 1.0\nk = "2 *"', "parameters.k", "bad expression"),
        ('m = 1.0\nk = { value = "1 ^ 2" }', "parameters.k.value", "use \\*\\*"),
        ('m = 1.0\nz = 0.0\nk = "1/z"', "parameters.k", "division by zero"),
        ("m = 1.0\nk = true", "parameters.k", "wrong type"),
        ("m = 1.0\nk = 1e400", "parameters.k", "finite"),
        (f"m = 1.0\nk = {10**400}", "parameters.k", "finite"),
    ],
)
def test_parameter_errors_name_file_key_and_fault(tmp_path, parameters, key, words):
    path = write(tmp_path, parameters)
    with pytest.raises(ModelError, match=words) as caught:
        load_model(path)
    assert caught.value.file == str(path) and caught.value.key == key
    assert str(caught.value).startswith(f"{path}: {key}: ")


def test_a_value_that_breaks_an_expression_at_run_time_names_the_key_and_the_values(tmp_path):
    model = load_model(write(tmp_path, 'm = 1.0\nV = 2.0\nk = "1/(V - 55)"'))
    with pytest.raises(ModelError, match=r"division by zero.*\(with V=55\)") as caught:
        model.system(parameters={"V": 55.0})
    assert caught.value.key == "parameters.k"


def test_a_long_chain_of_parameters_is_evaluated_without_recursion(tmp_path):
    chain = "\n".join(f'p{i} = "p{i + 1} + 1"' for i in range(3000))
    model = load_model(write(tmp_path, f'm = 1.0\nk = "p0"\n{chain}\np3000 = 1.0'))
    assert model.parameters["k"] == 3001.0


def test_shipped_models_are_found_by_name(tmp_path, monkeypatch):
    assert "wheelset" in shipped_models()
    monkeypatch.chdir(tmp_path)
    assert model_path("wheelset") == builtin_path("wheelset")
    assert model_path("wheelset.toml") == builtin_path("wheelset")
    with pytest.raises(ModelError, match="shipped models: .*wheelset"):
        load_model("no_such_model")
    # a file of that name in the working folder wins over the shipped one
    (tmp_path / "wheelset.toml").write_text(BASE.format(parameters="m = 1.0\nk = 4.0"))
    assert load_model("wheelset.toml").name == "oscillator"
