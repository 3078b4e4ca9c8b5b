"""``generate`` writes its three files all or nothing: a bad output path fails before the
translation, any failure leaves every existing file as it was (never a new netlist beside an
old bill of materials), and the files get the permissions an ordinary write would give."""

import importlib
import os
import stat
from dataclasses import replace
from pathlib import Path

import pytest

from circuitsim.cli import main
from circuitsim.mechanics import load_model
from circuitsim.netlist.errors import NetlistError
from circuitsim.synthesis.check import check_mapping
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions

MODELS = Path(__file__).parent / "models"
WHEELSET = Path(__file__).resolve().parents[2] / "circuitsim" / "mechanics" / "models"
# The module itself: the package re-exports the function under the same name.
generate_module = importlib.import_module("circuitsim.synthesis.generate")


@pytest.fixture(scope="module")
def system():
    return load_model(MODELS / "gap_oscillator.toml").system()


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every entry of ``folder``: a file's bytes, None for a folder."""
    return {p.name: (None if p.is_dir() else p.read_bytes()) for p in folder.iterdir()}


def test_a_folder_in_place_of_a_companion_changes_no_file(tmp_path, system):
    netlist = tmp_path / "w3.cir"
    generate(system, netlist)
    (tmp_path / "w3.scale.json").unlink()
    (tmp_path / "w3.scale.json").mkdir()
    before = snapshot(tmp_path)
    with pytest.raises(IsADirectoryError) as caught:
        generate(system, netlist, SynthesisOptions(opamp="tl074"))  # a different netlist
    assert str(caught.value) == f"cannot write {tmp_path / 'w3.scale.json'}: it is a directory"
    assert snapshot(tmp_path) == before  # the old netlist and BOM, no temporary file


@pytest.mark.parametrize(
    ("given", "error", "reason"),
    [
        ("nope/w.cir", FileNotFoundError, "folder nope does not exist"),
        (".", IsADirectoryError, "it is a directory"),
        ("./", IsADirectoryError, "it is a directory"),
        ("..", IsADirectoryError, "it is a directory"),
        ("/", IsADirectoryError, "it is a directory"),
    ],
)
def test_a_bad_output_path_fails_before_the_translation(
    tmp_path, monkeypatch, system, given, error, reason
):
    def no_translation(*args, **kwargs):
        raise AssertionError("translated although the output path is bad")

    monkeypatch.setattr(generate_module, "synthesize", no_translation)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(error) as caught:
        generate(system, given)
    assert str(caught.value) == f"cannot write {given}: {reason}"
    assert list(tmp_path.iterdir()) == []


def test_a_netlist_that_does_not_read_back_writes_nothing(tmp_path, system, monkeypatch):
    netlist = tmp_path / "w.cir"
    generate(system, netlist)
    before = snapshot(tmp_path)
    # A writer that emits a line no reader takes (a resistor with one node)
    written = generate_module.write_netlist(generate_module.synthesize(system).circuit)
    broken = written.replace(".end\n", "RBROKEN a\n.end\n")
    monkeypatch.setattr(generate_module, "write_netlist", lambda circuit, dialect, **_: broken)
    with pytest.raises(NetlistError, match="RBROKEN"):
        generate(system, netlist)
    assert snapshot(tmp_path) == before
    with pytest.raises(NetlistError):
        generate(system, tmp_path / "fresh.cir")
    assert snapshot(tmp_path) == before


def test_a_negative_stop_time_is_refused_before_anything_is_written(tmp_path, system):
    broken = replace(system, circuit_hints={**system.circuit_hints, "t_stop": -5.0})
    with pytest.raises(SynthesisError, match="t_stop"):
        generate(broken, tmp_path / "w.cir")
    assert snapshot(tmp_path) == {}


def test_the_report_is_the_check_of_the_files_written(tmp_path, system):
    result = generate(system, tmp_path / "w.cir", SynthesisOptions(series="E24"))
    from_disk = check_mapping(result.netlist, result.scale_file, system, bom=result.bom_file)
    assert result.report.ok and from_disk.ok
    assert result.report.summary() == from_disk.summary()


def test_files_get_the_permissions_an_ordinary_write_gives(tmp_path, system):
    netlist = tmp_path / "w.cir"
    old = os.umask(0o022)
    try:
        generate(system, netlist)
        assert {stat.S_IMODE(p.stat().st_mode) for p in tmp_path.iterdir()} == {0o644}
        os.chmod(netlist, 0o600)  # the user's choice for the netlist survives regeneration
        generate(system, netlist, SynthesisOptions(series="E96"))
    finally:
        os.umask(old)
    assert stat.S_IMODE(netlist.stat().st_mode) == 0o600
    assert stat.S_IMODE((tmp_path / "w.bom.csv").stat().st_mode) == 0o644
    assert "E96" in (tmp_path / "w.bom.csv").read_text()


def test_cli_bad_circuit_t_stop_names_the_model_key_and_writes_nothing(tmp_path, capsys):
    text = (WHEELSET / "wheelset.toml").read_text()
    assert "\nt_stop = 5.0\n" in text
    model = tmp_path / "gc.toml"
    model.write_text(text.replace("\nt_stop = 5.0\n", "\nt_stop = -5.0\n"))
    code = main(["generate", "--model", str(model), "-o", str(tmp_path / "gc3.cir")])
    assert code == 2  # 1 is kept for a failed mapping check
    err = capsys.readouterr().err
    assert f"{model}: circuit.t_stop: must be a positive number of seconds, got -5.0" in err
    assert [p.name for p in tmp_path.iterdir()] == ["gc.toml"]


def test_cli_companion_is_a_directory(tmp_path, capsys):
    out = tmp_path / "w.cir"
    (tmp_path / "w.bom.csv").mkdir()
    code = main(["generate", "--tstop", "1", "-o", str(out)])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert (
        err
        == f"circuitsim generate: error: cannot write {tmp_path / 'w.bom.csv'}: it is a directory"
    )
    assert [p.name for p in tmp_path.iterdir()] == ["w.bom.csv"]
