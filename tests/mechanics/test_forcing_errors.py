"""Every key of the forcing kinds gets a ``FILE: KEY: MESSAGE`` error (docs/model.md)."""

import pytest

from circuitsim.mechanics import ModelError, load_model

HEADER = """
[model]
name = "lag"
kind = "first_order"
[states]
names = ["x"]
units = ["m"]
[parameters]
a = 3.0
V = 0.0
[matrices]
A = [["-a"]]
"""

CASES = [
    ('kind = "ramp"\nenters = { x = 1 }', "forcing.u.kind", "must be one of"),
    ('kind = "step"\nenters = { x = 1 }', "forcing.u.amplitude", "missing key"),
    ('kind = "step"\namplitude = 1\nfrequency = 2\nenters = { x = 1 }', "forcing.u.frequency",
     "unknown key"),
    ('kind = "step"\namplitude = 1\nrise = -1\nenters = { x = 1 }', "forcing.u.rise",
     "0 or positive"),
    ('kind = "bump"\namplitude = 1\nenters = { x = 1 }', "forcing.u.duration", "missing key"),
    ('kind = "bump"\namplitude = 1\nduration = 0\nenters = { x = 1 }', "forcing.u.duration",
     "must be positive"),
    ('kind = "bump"\namplitude = 1\nduration = 1\nshape = "square"\nenters = { x = 1 }',
     "forcing.u.shape", "haversine or half_sine"),
    ('kind = "sines"\namplitudes = [1, 2]\nfrequencies = [1]\nenters = { x = 1 }',
     "forcing.u.frequencies", "wrong length"),
    ('kind = "sines"\namplitudes = []\nfrequencies = []\nenters = { x = 1 }',
     "forcing.u.amplitudes", "non-empty array"),
    ('kind = "series"\nenters = { x = 1 }', "forcing.u", "exactly one of file"),
    ('kind = "series"\npoints = [[0, 1]]\nfile = "a.csv"\nenters = { x = 1 }', "forcing.u",
     "exactly one of file"),
    ('kind = "series"\npoints = [[0, 1]]\nenters = { x = 1 }', "forcing.u.points",
     "at least 2 points"),
    ('kind = "series"\npoints = [[0, 1], [1]]\nenters = { x = 1 }', "forcing.u.points",
     "point 1: expected a [time, value] pair"),
    ('kind = "series"\npoints = [[0, 1], [1, "x"]]\nenters = { x = 1 }', "forcing.u.points",
     "point 1: expected a number"),
    ('kind = "series"\npoints = [[0, 1], [-1, 2]]\nenters = { x = 1 }', "forcing.u.points",
     "point 1: time -1 is before the previous 0"),
    ('kind = "series"\npoints = [[0, 1], [1, 2], [1, 3], [1, 4]]\nenters = { x = 1 }',
     "forcing.u.points", "point 3: three points at time 1"),
    ('kind = "series"\npoints = [[0, 1], [1, 2]]\ntime_unit = "days"\nenters = { x = 1 }',
     "forcing.u.time_unit", "unknown time unit 'days'"),
    ('kind = "series"\npoints = [[0, 1], [1, 2]]\nunit = "m"\nvalue_unit = "N"\n'
     'enters = { x = 1 }', "forcing.u.value_unit", "cannot convert 'N'"),
    ('kind = "series"\npoints = [[0, 1], [1, 2]]\nspeed = "V"\nenters = { x = 1 }',
     "forcing.u.speed", "must be positive"),
    ('kind = "series"\nfile = "missing.csv"\nenters = { x = 1 }', "forcing.u.file",
     "file not found"),
]  # fmt: skip


@pytest.mark.parametrize(("body", "key", "message"), CASES)
def test_forcing_errors_name_file_and_key(tmp_path, body, key, message):
    path = tmp_path / "m.toml"
    path.write_text(HEADER + "[forcing.u]\n" + body + "\n")
    with pytest.raises(ModelError) as caught:
        load_model(path)
    text = str(caught.value)
    assert text.startswith(f"{path}: {key}: "), text
    assert message in text, text


@pytest.mark.parametrize(
    ("csv", "message"),
    [
        ("time,value\n0,1\n1,2,3\n", "p.csv line 3: expected two columns (time, value), got 3"),
        ("time,value\n0,1\n1,abc\n", "p.csv line 3: expected a number, got 'abc'"),
        ("0,1\nt,v\n", "p.csv line 2: expected a number, got 't'"),
        ("0,1\n1,nan\n", "p.csv line 2: must be finite"),
    ],
)
def test_csv_errors_name_the_line(tmp_path, csv, message):
    (tmp_path / "p.csv").write_text(csv)
    path = tmp_path / "m.toml"
    path.write_text(HEADER + '[forcing.u]\nkind = "series"\nfile = "p.csv"\nenters = { x = 1 }\n')
    with pytest.raises(ModelError) as caught:
        load_model(path)
    assert str(caught.value).startswith(f"{path}: forcing.u.file: "), str(caught.value)
    assert message in str(caught.value)
