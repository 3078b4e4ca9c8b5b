"""Hostile model files (the reliability probe of issue 21) end in a ModelError naming the file,
the key and the fault: never a RecursionError, OverflowError or tomllib's ValueError."""

import sys
from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.mechanics import ModelError, load_model
from circuitsim.mechanics.expressions import MAX_DEPTH, MAX_NESTING, ExpressionError, parse
from circuitsim.mechanics.modelfile import MAX_FILE_BYTES

FIRST_ORDER = """
[model]
name = "hostile"
kind = "first_order"

[states]
names = ["x"]

[parameters]
k = {parameter}

[matrices]
A = [[{entry}]]
"""


def write(tmp_path, entry="-1.0", parameter="1.0"):
    path = tmp_path / "hostile.toml"
    path.write_text(FIRST_ORDER.format(entry=entry, parameter=parameter))
    return path


def model_error(path) -> ModelError:
    with pytest.raises(ModelError) as caught:
        load_model(path)
    assert caught.value.file == str(path)
    return caught.value


@pytest.mark.parametrize(
    "entry, words",
    [
        ('"' + "+".join(["1"] * 1500) + '"', "more than 300 operations in a chain"),
        ('"' + "(" * 1200 + "1" + ")" * 1200 + '"', "nested too deeply"),
        ('"' + "-" * 1500 + "1" + '"', "nested too deeply"),
        ('"' + "sqrt(" * 500 + "1" + ")" * 500 + '"', "nested too deeply"),
        ('"2' + "**2" * 500 + '"', "nested too deeply"),
        ("1" * 401, "number too large: an integer of 401 digits"),
    ],
    ids=["1500-term sum", "1200 parentheses", "1500 minus signs", "500 calls", "500 powers",
         "401-digit integer"],
)  # fmt: skip
def test_a_hostile_coefficient_is_a_model_error_naming_its_key(tmp_path, entry, words):
    error = model_error(write(tmp_path, entry=entry))
    assert error.key == "matrices.A[0][0]"
    assert words in error.message
    assert len(str(error)) < 400  # the expression is quoted cut short, not thousands of chars


def test_a_5000_digit_integer_is_refused_with_its_line(tmp_path):
    path = write(tmp_path, entry="1" * 5000)
    error = model_error(path)
    assert error.message == "not valid TOML: an integer of more than 4,300 digits (line 13)"


@pytest.mark.parametrize(
    "parameter, words",
    [
        ("1" * 401, f"must be a finite number, got {'1' * 401}"),
        ("inf", "must be a finite number, got inf"),
        ("nan", "must be a finite number, got nan"),
    ],
)
def test_a_parameter_beyond_the_float_range_is_refused(tmp_path, parameter, words):
    error = model_error(write(tmp_path, parameter=parameter))
    assert (error.key, error.message) == ("parameters.k", words)


@pytest.mark.parametrize("nested", ["[" * 5000 + "]" * 5000, "{b=" * 3000 + "1" + "}" * 3000])
def test_deeply_nested_toml_is_refused(tmp_path, nested):
    path = tmp_path / "nested.toml"
    path.write_text(f"a = {nested}\n")
    assert model_error(path).message == "not valid TOML: arrays or tables nested too deeply"


def test_a_file_past_the_size_limit_is_refused_before_reading(tmp_path):
    path = write(tmp_path)
    with open(path, "ab") as handle:
        handle.truncate(MAX_FILE_BYTES + 1)  # sparse: no memory or disk used
    error = model_error(path)
    assert error.message.startswith(f"too large: {MAX_FILE_BYTES + 1:,} bytes")


def test_a_folder_is_not_a_model_file(tmp_path):
    assert model_error(tmp_path).message == "is a folder, not a model file"


def test_the_limits_leave_room_below_the_recursion_limit():
    # the deepest accepted expressions still parse and evaluate from a deep call stack
    nested = "(" * MAX_NESTING + "1" + ")" * MAX_NESTING
    chain = "+".join(["1"] * MAX_DEPTH)
    signs = "-" * MAX_NESTING + "2"

    def deep(levels):
        if levels:
            return deep(levels - 1)
        return [parse(text)({}) for text in (nested, chain, signs)]

    assert deep(sys.getrecursionlimit() // 4) == [1.0, float(MAX_DEPTH), 2.0]
    with pytest.raises(ExpressionError, match="nested too deeply"):
        parse("(" * (MAX_NESTING + 1) + "1" + ")" * (MAX_NESTING + 1))
    with pytest.raises(ExpressionError, match="operations in a chain"):
        parse("+".join(["1"] * (MAX_DEPTH + 1)))


def test_the_cli_prints_one_line_and_exits_2(tmp_path, capsys):
    path = write(tmp_path, entry='"' + "(" * 1200 + "1" + ")" * 1200 + '"')
    assert main(["ode", "--model", str(path), "--tstop", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"circuitsim ode: error: {path}: matrices.A[0][0]:")


@pytest.mark.parametrize(
    "path, words",
    [("x" * 5000, "cannot read: File name too long"), ("a\x00b", "contains a NUL character")],
    ids=["5000 characters", "NUL"],
)
def test_unreadable_paths_are_model_errors(tmp_path, path, words):
    with pytest.raises(ModelError, match=words):
        load_model(str(tmp_path / path))


def test_help_with_an_unreadable_model_is_the_generic_help(tmp_path, capsys):
    with pytest.raises(SystemExit) as caught:
        main(["ode", "--model", str(tmp_path / ("x" * 5000)), "--help"])
    assert caught.value.code == 0
    assert "the built-in wheelset" in capsys.readouterr().out


MODELS = Path(__file__).resolve().parents[1] / "synthesis" / "models"
SHIPPED = Path(__file__).resolve().parents[2] / "circuitsim" / "mechanics" / "models"


@pytest.mark.parametrize(
    "source, old, new, key, words",
    [
        (MODELS / "driven_oscillator.toml", "[0.5, 10]", "[0.5, " + "1" * 401 + "]",
         "forcing.road.points", "must be finite"),
        (SHIPPED / "wheelset.toml", '"track_irregularity.csv"', '"' + "a" * 5000 + '"',
         "forcing.irregularity.file", "cannot read: File name too long"),
    ],
    ids=["401-digit point", "5000-character file name"],
)  # fmt: skip
def test_time_series_forcing_found_by_the_fuzzer(tmp_path, source, old, new, key, words):
    # gen_models seed 5: an OverflowError and an OSError escaped the forcing reader
    text = source.read_text()
    assert old in text
    path = tmp_path / "m.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(ModelError, match=words) as caught:
        load_model(path)
    assert caught.value.key == key
