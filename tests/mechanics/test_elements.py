"""Models from elements (circuitsim/mechanics/elements.py): the assembly against the same
model typed as matrices, and every mistake a ModelError naming the file and the key."""

import textwrap

import numpy as np
import pytest

from circuitsim.mechanics import ModelError, load_model
from circuitsim.mechanics.elements import linear_form
from circuitsim.mechanics.expressions import Expression, evaluate, parse

HEAD = """
[model]
name = "two_masses"
kind = "second_order"

[coordinates]
names = ["x", "th"]
units = ["m", "rad"]

[parameters]
m = 3.0
J = 0.5
k = 400.0
k2 = 150.0
c = 7.0
r = 0.2
g_s = -30.0
f = 900.0
V = 12.0
kc = 5000.0
gap = 0.01
twice_k = "2*k"
"""

# x: a mass on a spring to ground and a damper; th: a rocker of radius r coupled to x by the
# spring k2 acting on x - r*th; a signed stiffness on th; a creep-like element (force
# -f (x'/V - th) on x); a contact on x - r*th beyond the gap
ELEMENTS = """
[elements.masses]
x = "m"
th = "J"

[elements.springs]
ground = { stiffness = "twice_k", deflection = "x" }
coupling = { stiffness = "k2", deflection = "x - r*th" }

[elements.dampers]
damper = { damping = "c", deflection = "x" }

[elements.gravitational]
tip = { stiffness = "g_s", deflection = "th" }

[elements.creep]
slip = { coefficient = "f", speed = "V", along = "x", creepage = "-th" }

[elements.contacts]
stop = { stiffness = "kc", clearance = "gap", deflection = "x - r*th" }
"""

# the same model written out by hand
MATRICES = """
[matrices]
M = [["m", 0], [0, "J"]]
C = [["c + f/V", 0], [0, 0]]
K = [["2*k + k2", "-k2*r - f"], ["-k2*r", "k2*r**2 + g_s"]]

[nonlinear.stop]
enters = { x = 1, th = "-r" }
deadzone = { row = { x = 1, th = "-r" }, eta = "gap", slope = "kc" }
"""


def write(tmp_path, text, name="model.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def assert_same_system(ours, theirs):
    np.testing.assert_allclose(ours.A, theirs.A, rtol=1e-14, atol=0)
    assert [t.name for t in ours.nonlinear] == [t.name for t in theirs.nonlinear]
    for a, b in zip(ours.nonlinear, theirs.nonlinear, strict=True):
        np.testing.assert_allclose(a.direction, b.direction, rtol=1e-14, atol=0)
        np.testing.assert_allclose(a.linear, b.linear, rtol=1e-14, atol=0)
        assert len(a.abs_terms) == len(b.abs_terms) == 2
        for p, q in zip(a.abs_terms, b.abs_terms, strict=True):
            assert (p.gain, p.offset) == pytest.approx((q.gain, q.offset), rel=1e-14)
            np.testing.assert_allclose(p.row, q.row, rtol=1e-14, atol=0)


@pytest.mark.parametrize(
    "parameters", [{}, {"V": 30.0}, {"k": 10.0, "r": 0.5}, {"g_s": 12.0, "f": 0.0}]
)
def test_elements_assemble_to_the_matrices_typed_by_hand(tmp_path, parameters):
    ours = load_model(write(tmp_path, HEAD + ELEMENTS, "elements.toml"))
    theirs = load_model(write(tmp_path, HEAD + MATRICES, "matrices.toml"))
    assert ours.nonlinear_terms == {"stop": True}
    assert_same_system(ours.system(parameters=parameters), theirs.system(parameters=parameters))


def test_the_assembled_entries_stay_expressions_of_the_parameters(tmp_path):
    model = load_model(write(tmp_path, HEAD + ELEMENTS))
    K = model.spec.matrices["K"]
    assert K[0][1].expression.names == {"k2", "r", "f"}
    assert K[0][0].key == "elements.K[x][x]"
    # the derived parameter follows its primary one: 2k moves with k
    k_entry = [model.system(parameters={"k": k}).A[2, 0] for k in (100.0, 200.0)]
    assert k_entry[0] - k_entry[1] == pytest.approx(2 * 100.0 / 3.0, rel=1e-14)


def test_matrices_given_too_are_added_to_the_assembly(tmp_path):
    extra = '\n[matrices]\nK = [[1.5, 0], [0, 0]]\nF = ["0.25", 0]\n'
    ours = load_model(write(tmp_path, HEAD + ELEMENTS + extra, "both.toml"))
    theirs = load_model(write(tmp_path, HEAD + MATRICES.replace('"2*k + k2"', '"2*k + k2 + 1.5"')
                              .replace("[matrices]", '[matrices]\nF = ["0.25", 0]'),
                              "hand.toml"))  # fmt: skip
    assert_same_system(ours.system(), theirs.system())
    np.testing.assert_allclose(ours.system().b0, [0, 0, 0.25 / 3.0, 0], rtol=1e-15)


@pytest.mark.parametrize(
    "text, weights",
    [
        ("x", {0: 1.0}),
        ("x - r*th", {0: 1.0, 1: -0.2}),
        ("-(x + th)/2", {0: -0.5, 1: -0.5}),
        ("2*(x - 3*th)*r", {0: 0.4, 1: -1.2}),
        ("x - x + th", {0: 0.0, 1: 1.0}),
        ("sqrt(k)*th + 0*x", {1: 20.0}),
    ],
)
def test_linear_form_gives_the_weights(text, weights):
    def fail(key, message):
        return ModelError(message, key=key)

    form = linear_form(parse(text).tree, ("x", "th"), {"r", "k"}, "key", fail)
    values = {i: evaluate(Expression("", tree), {"r": 0.2, "k": 400.0}) for i, tree in form.items()}
    assert values.keys() >= {i for i, w in weights.items() if w != 0}
    for index, weight in weights.items():
        assert values.get(index, 0.0) == pytest.approx(weight, abs=1e-15)


ERRORS = [
    # (a change of HEAD + ELEMENTS, the key, words of the message)
    (
        ('deflection = "x"', 'deflection = "z"'),
        "elements.springs.ground.deflection",
        "unknown coordinate or parameter 'z'",
    ),
    (('x = "m"\n', 'x = "m"\nz = "m"\n'), "elements.masses.z", "unknown coordinate"),
    (('th = "J"\n', ""), "elements.masses", "missing mass for th"),
    (('th = "J"', 'th = "-J"'), "elements.masses.th", "must be positive, got -0.5"),
    (
        ('"twice_k"', '"-k"'),
        "elements.springs.ground.stiffness",
        "must not be negative, got -400 (a signed stiffness is [elements.gravitational])",
    ),
    (
        ('damping = "c"', 'damping = "-c"'),
        "elements.dampers.damper.damping",
        "must not be negative",
    ),
    (
        ('clearance = "gap"', "clearance = 0"),
        "elements.contacts.stop.clearance",
        "must be positive",
    ),
    (('speed = "V"', 'speed = "V - 12"'), "elements.creep.slip.speed", "must be positive, got 0"),
    (('coefficient = "f"', 'coefficient = "-f"'), "elements.creep.slip.coefficient", "negative"),
    (
        ('"x - r*th" }\n\n[elements.dampers]', '"x*th" }\n\n[elements.dampers]'),
        "elements.springs.coupling.deflection",
        "a product of coordinates",
    ),
    (
        ('deflection = "th" }', 'deflection = "sin(th)" }'),
        "elements.gravitational.tip.deflection",
        "a coordinate inside sin()",
    ),
    (
        ('deflection = "x" }\ncoupling', 'deflection = "x - gap" }\ncoupling'),
        "elements.springs.ground.deflection",
        "a part without a coordinate ('-gap')",
    ),
    (
        ('deflection = "x" }\ncoupling', 'deflection = "r" }\ncoupling'),
        "elements.springs.ground.deflection",
        "names no coordinate",
    ),
    (
        ('deflection = "x" }\ncoupling', 'deflection = "x/th" }\ncoupling'),
        "elements.springs.ground.deflection",
        "a coordinate in a denominator",
    ),
    (
        ('deflection = "x" }\ncoupling', 'deflection = "x_dot" }\ncoupling'),
        "elements.springs.ground.deflection",
        "write the coordinate",
    ),
    (
        ('deflection = "x" }\ncoupling', 'deflection = "x", k = 1 }\ncoupling'),
        "elements.springs.ground.k",
        "unknown key",
    ),
    (('stiffness = "twice_k", ', ""), "elements.springs.ground.stiffness", "missing key"),
    (
        ('stiffness = "twice_k"', 'stiffness = "twice_k/0"'),
        "elements.springs.ground.stiffness",
        "division by zero",
    ),
    (("[elements.dampers]", "[elements.masks]"), "elements.masks", "unknown key"),
    (('along = "x"', 'along = "x**2"'), "elements.creep.slip.along", "a coordinate inside a power"),
    (
        ("m = 3.0\n", "m = 3.0\nx = 1.0\n"),
        "elements.springs.ground.deflection",
        "'x' is both a coordinate and a parameter",
    ),
]


@pytest.mark.parametrize("change, key, words", ERRORS, ids=[e[1] + ":" + e[2] for e in ERRORS])
def test_a_mistake_names_the_file_and_the_key(tmp_path, change, key, words):
    text = HEAD + ELEMENTS
    assert change[0] in text
    path = write(tmp_path, text.replace(change[0], change[1], 1))
    with pytest.raises(ModelError) as caught:
        load_model(path)
    error = caught.value
    assert error.file == str(path)
    assert error.key == key, str(error)
    assert words in error.message
    assert str(error).startswith(f"{path}: {key}: ")


def test_a_contact_may_not_reuse_a_nonlinear_groups_name(tmp_path):
    extra = "\n[nonlinear.stop]\nenters = { x = 1 }\nlinear = { x = 1 }\n"
    with pytest.raises(ModelError, match="a \\[nonlinear\\] group is also named 'stop'") as caught:
        load_model(write(tmp_path, HEAD + ELEMENTS + extra))
    assert caught.value.key == "elements.contacts.stop"


def test_a_first_order_model_has_no_elements(tmp_path):
    text = """
    [model]
    name = "decay"
    kind = "first_order"
    [states]
    names = ["x"]
    [matrices]
    A = [[-1]]
    [elements.masses]
    x = 1
    """
    with pytest.raises(ModelError, match="only a second_order model") as caught:
        load_model(write(tmp_path, text))
    assert caught.value.key == "elements"


def test_without_matrices_or_elements_the_matrices_are_missing(tmp_path):
    text = HEAD  # neither [matrices] nor [elements]
    with pytest.raises(ModelError, match="missing table") as caught:
        load_model(write(tmp_path, text))
    assert caught.value.key == "matrices"


def test_the_example_of_docs_model_md_assembles_what_the_text_says(tmp_path):
    from pathlib import Path

    text = (Path(__file__).parents[2] / "docs" / "model.md").read_text()
    section = text.split("## Elements:", 1)[1].split("\n## ", 1)[0]
    example = section.split("```toml\n", 1)[1].split("```", 1)[0]
    values = dict(m=1500.0, I=1200.0, m_f=2600.0, Ky=2.4e6, K_f=3e5, C_f=3e4, W=21600.0,
                  b=0.74, r0=0.44, f11=3.98e6, f22=3.62e6, V=30.0, k=1.7e7, eta=0.009)  # fmt: skip
    values["lambda"] = 0.3
    head = '[model]\nname = "example"\nkind = "second_order"\n[parameters]\n' + "".join(
        f"{name} = {value!r}\n" for name, value in values.items()
    )
    model = load_model(write(tmp_path, head + example))
    v = values
    k_g = v["W"] * v["lambda"] / v["b"]
    M = np.diag([v["m"], v["I"], v["m_f"]])
    C = np.diag([2 * v["f22"] / v["V"], 2 * v["f11"] * v["b"] ** 2 / v["V"], v["C_f"]])
    K = np.array([
        [2 * v["Ky"] + k_g, -2 * v["f22"], -2 * v["Ky"]],
        [2 * v["f11"] * v["b"] * v["lambda"] / v["r0"], -v["W"] * v["b"] * v["lambda"], 0],
        [-2 * v["Ky"], 0, 2 * v["Ky"] + v["K_f"]],
    ])  # fmt: skip
    inverse = np.linalg.inv(M)
    A = model.system().A
    np.testing.assert_allclose(A[3:, :3], -inverse @ K, rtol=1e-14, atol=0)
    np.testing.assert_allclose(A[3:, 3:], -inverse @ C, rtol=1e-14, atol=0)
    (flange,) = model.system().nonlinear
    assert flange.name == "flange" and flange.direction[3] == pytest.approx(-1 / v["m"])


def test_thousands_of_elements_on_one_coordinate_load(tmp_path):
    """Each entry is a balanced sum of its terms: 3000 springs stay a shallow expression."""
    springs = "".join(f'k{i} = {{ stiffness = "k", deflection = "x" }}\n' for i in range(3000))
    text = HEAD + '\n[elements.masses]\nx = "m"\nth = "J"\n[elements.springs]\n' + springs
    model = load_model(write(tmp_path, text))
    assert model.system().A[2, 0] == pytest.approx(-3000 * 400.0 / 3.0, rel=1e-13)
