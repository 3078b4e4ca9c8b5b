"""compare with a circuit or results made elsewhere; simulate's columns, probes and states.

- ``compare --netlist F.cir [--scale] [--engine]``: an existing netlist, simulated here.
- ``compare --raw F.raw --scale``: results ngspice wrote (binary and ASCII) or in LTspice's
  format (UTF-16, float32 values; written by spicelib's RawWrite from ngspice's results).
  The reference is the direct ODE solution; the same ngspice results compared through the
  raw file and through ``--netlist --engine ngspice`` give the same metrics.
- ``simulate``: the same columns from both engines, unknown probes refused before ngspice
  runs, ``--states`` the physical states (node voltage / volts_per_unit).
"""

import json
import shutil
import subprocess

import numpy as np
import pytest

from circuitsim.cli import main
from circuitsim.interop.rawfile import read_rawfile
from circuitsim.solver.waveforms import Waveforms
from circuitsim.synthesis.scalemap import ScaleMap
from tests.conftest import requires_ngspice

T_STOP = 0.5  # model seconds: the wheelset's first swings, enough to compare


@pytest.fixture(scope="module")
def wheelset(tmp_path_factory):
    """A generated wheelset netlist (ideal op-amps, exact values, flange) and its scale file."""
    from circuitsim.mechanics import load_model
    from circuitsim.synthesis.generate import generate
    from circuitsim.synthesis.options import SynthesisOptions

    folder = tmp_path_factory.mktemp("wheelset")
    system = load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.040})
    result = generate(system, folder / "w.cir", SynthesisOptions(t_stop=T_STOP, series="exact"))
    return result.netlist, result.scale_file


def _ngspice_raw(netlist, raw, ascii: bool):
    env = {"PATH": "/usr/bin:/bin", "HOME": str(raw.parent)}
    if ascii:
        env["SPICE_ASCIIRAWFILE"] = "1"
    subprocess.run(
        ["ngspice", "-b", "-n", "-r", str(raw), str(netlist)],
        cwd=raw.parent,
        env=env,
        capture_output=True,
        check=True,
        timeout=300,
    )
    return raw


def _compare_json(capsys, *argv) -> tuple[int, dict]:
    code = main(["compare", "--json", *argv])
    return code, json.loads(capsys.readouterr().out)


def _nrmsd(data: dict) -> dict[str, float]:
    return {state: m["nrmsd_percent"] for state, m in data["states"].items()}


@requires_ngspice
def test_raw_files_from_ngspice_compare_like_the_netlist_run(wheelset, tmp_path, capsys):
    netlist, scale = wheelset
    code, direct = _compare_json(capsys, "--netlist", str(netlist), "--engine", "ngspice")
    assert code == 0 and direct["passed"], direct
    assert direct["engine"] == "ngspice"
    binary = _ngspice_raw(netlist, tmp_path / "b.raw", ascii=False)
    text = _ngspice_raw(netlist, tmp_path / "a.raw", ascii=True)
    assert b"Binary:" in binary.read_bytes() and b"Values:" in text.read_bytes()
    for raw in (binary, text):
        code, data = _compare_json(capsys, "--raw", str(raw), "--scale", str(scale))
        assert code == 0 and data["passed"], data
        assert data["engine"] == "ngspice"
        # the same ngspice run: the same metrics (ASCII carries 16 digits, binary all 17)
        for state, value in _nrmsd(data).items():
            assert value == pytest.approx(direct["states"][state]["nrmsd_percent"], rel=1e-6)
        assert max(_nrmsd(data).values()) < 0.5  # within the ideal op-amps' threshold


@requires_ngspice
def test_an_ltspice_format_raw_file_compares(wheelset, tmp_path, capsys):
    from spicelib.raw.raw_write import RawWrite, Trace

    netlist, scale = wheelset
    waves = read_rawfile(_ngspice_raw(netlist, tmp_path / "b.raw", ascii=False))
    code, want = _compare_json(capsys, "--raw", str(tmp_path / "b.raw"), "--scale", str(scale))
    assert code == 0
    for fast in (True, False):  # fastaccess: vector after vector
        writer = RawWrite(fastacces=fast)
        writer.add_trace(Trace("time", waves.time))
        for name in waves.names:
            writer.add_trace(Trace(name.upper(), waves[name].astype(np.float32)))
        path = tmp_path / f"lt{int(fast)}.raw"
        writer.save(path)
        assert path.read_bytes()[:4] == "Ti".encode("utf_16_le")
        read = read_rawfile(path)
        assert read.engine == "ltspice" and read.names == waves.names
        np.testing.assert_array_equal(read.time, waves.time)
        np.testing.assert_array_equal(read["v(y)"], waves["v(y)"].astype(np.float32))
        code, data = _compare_json(capsys, "--raw", str(path), "--scale", str(scale))
        assert code == 0 and data["engine"] == "ltspice"
        for state, value in _nrmsd(data).items():  # float32: ~1e-7 of the range
            assert value == pytest.approx(want["states"][state]["nrmsd_percent"], abs=1e-4)


def test_a_given_netlist_runs_in_the_builtin_engine(wheelset, capsys):
    netlist, _ = wheelset
    code, data = _compare_json(capsys, "--netlist", str(netlist))  # scale file beside it
    assert code == 0 and data["passed"], data
    assert data["engine"] == "builtin" and data["netlist"] == str(netlist)
    assert max(_nrmsd(data).values()) < 0.5


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--raw", "x.raw"], "--raw needs --scale"),
        (["--netlist", "a.cir", "--raw", "x.raw"], "give --netlist"),
        (["--scale", "s.json"], "--scale goes with"),
        (["--netlist", "a.cir", "--series", "E96"], "--series"),
        (["--raw", "x.raw", "--scale", "s.json", "--engine", "ngspice"], "--engine"),
        (["--netlist", "{tmp}/none.cir"], "no such file"),
        (["--netlist", "."], "--netlist .: no such file"),
        (["--raw", "{tmp}/none.raw", "--scale", "s.json"], "no such file"),
    ],
)
def test_given_inputs_refused_with_a_reason(argv, words, tmp_path, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    assert main(["compare", *argv]) == 2
    assert words in capsys.readouterr().err


def test_a_netlist_without_its_scale_file_is_refused(wheelset, tmp_path, capsys):
    lone = tmp_path / "lone.cir"
    shutil.copy(wheelset[0], lone)
    assert main(["compare", "--netlist", str(lone)]) == 2
    assert "no scale file" in capsys.readouterr().err


def test_a_raw_file_that_is_not_one_is_named(wheelset, tmp_path, capsys):
    _, scale = wheelset
    bad = tmp_path / "bad.raw"
    bad.write_text("hello\n")
    assert main(["compare", "--raw", str(bad), "--scale", str(scale)]) == 2
    assert str(bad) in capsys.readouterr().err


# --- simulate -------------------------------------------------------------------------------


def _short_copy(netlist, tmp_path):
    """The netlist with a 20 ms .tran (the columns do not depend on the length)."""
    lines = netlist.read_text().splitlines()
    lines = [".tran 1m 20m 0 1m uic" if x.startswith(".tran") else x for x in lines]
    short = tmp_path / "short.cir"
    short.write_text("\n".join(lines) + "\n")
    shutil.copy(netlist.with_suffix("").with_suffix(".scale.json"), tmp_path / "short.scale.json")
    return short


@requires_ngspice
def test_both_engines_write_the_same_columns(wheelset, tmp_path, capsys):
    short = _short_copy(wheelset[0], tmp_path)
    for engine in ("builtin", "ngspice"):
        out = tmp_path / f"{engine}.csv"
        assert main(["simulate", str(short), "--engine", engine, "--csv", str(out)]) == 0
    capsys.readouterr()
    builtin = Waveforms.from_csv(tmp_path / "builtin.csv")
    ngspice = Waveforms.from_csv(tmp_path / "ngspice.csv")
    assert builtin.names == ngspice.names
    assert len(builtin.names) > 30 and "v(y)" in builtin.names and "i(vxfg1)" in builtin.names


@requires_ngspice
def test_an_unknown_probe_is_refused_before_ngspice_runs(wheelset, tmp_path, capsys, monkeypatch):
    import circuitsim.interop.ngspice as ngspice

    def no_run(*args, **kwargs):
        raise AssertionError("ngspice ran")

    monkeypatch.setattr(ngspice, "run_ngspice", no_run)
    short = _short_copy(wheelset[0], tmp_path)
    code = main(["simulate", str(short), "--engine", "ngspice", "--probe", "v(nope)"])
    assert code == 2
    assert "no signal v(nope)" in capsys.readouterr().err


@pytest.mark.parametrize("engine", ["builtin", pytest.param("ngspice", marks=requires_ngspice)])
def test_states_are_node_voltages_through_the_scale_file(wheelset, tmp_path, capsys, engine):
    short = _short_copy(wheelset[0], tmp_path)
    scale = ScaleMap.load(tmp_path / "short.scale.json")
    volts, states = tmp_path / "v.csv", tmp_path / "s.csv"
    nodes = [s.node for s in scale.states.values()]
    assert main(["simulate", str(short), "--engine", engine, "--csv", str(volts), "--probe",
                 *nodes]) == 0  # fmt: skip
    assert main(["simulate", str(short), "--engine", engine, "--csv", str(states), "--states",
                 str(tmp_path / "short.scale.json")]) == 0  # fmt: skip
    capsys.readouterr()
    v, s = Waveforms.from_csv(volts), Waveforms.from_csv(states)
    assert s.names == list(scale.states)
    np.testing.assert_allclose(s.time, v.time * scale.time_scale, rtol=1e-15)
    for state, entry in scale.states.items():
        want = v[f"v({entry.node})"] / entry.volts_per_unit
        np.testing.assert_allclose(s[state], want, rtol=1e-14, atol=0)
