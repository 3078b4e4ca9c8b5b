"""``circuitsim compare``: the table, the JSON object and the exit codes."""

import json
import shutil

import pytest

from circuitsim.cli import main

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

SHORT = ["--engine", "ngspice", "--freq", "10", "--tstop", "0.6"]


@requires_ngspice
def test_compare_json_has_every_metric_per_state_and_exit_code_0(capsys, tmp_path):
    plot = tmp_path / "overlay.png"
    code = main(["compare", *SHORT, "--json", "--plot", str(plot)])
    data = json.loads(capsys.readouterr().out)
    assert code == 0 and data["passed"] is True
    assert set(data["states"]) == {"y", "psi", "y_dot", "psi_dot"}
    for metrics in data["states"].values():
        for key in ("nrmsd_percent", "max_abs_error", "peak_ratio", "frequency_ratio"):
            assert isinstance(metrics[key], float)
        assert isinstance(metrics["phase_lag_s"], float)
        assert metrics["nrmsd_percent"] < 0.5
    assert data["critical_speed_circuit"] == pytest.approx(55.6455, abs=1e-3)
    assert plot.read_bytes()[:4] == b"\x89PNG"


@requires_ngspice
def test_compare_exit_code_1_when_a_metric_is_beyond_its_threshold(capsys):
    # A threshold far below what any real simulation reaches (ngspice's own step error).
    code = main(["compare", *SHORT, "--max-nrmsd", "1e-9"])
    out = capsys.readouterr().out
    assert code == 1
    assert "FAIL: y: nrmsd_percent" in out


def test_compare_bad_scenario_is_an_error_with_exit_code_2(capsys):
    code = main(["compare", "--engine", "ngspice", "--param", "nosuch=1"])
    assert code == 2
    assert "nosuch" in capsys.readouterr().err


def test_compare_says_what_it_wrote_and_keeps_json_alone_on_stdout(capsys, tmp_path):
    netlist, plot = tmp_path / "c.cir", tmp_path / "o.png"
    argv = ["compare", "--tstop", "0.3", "--write-netlist", str(netlist), "--plot", str(plot)]
    main(argv)
    out = capsys.readouterr().out
    assert (
        f"wrote {netlist}, {tmp_path / 'c.scale.json'}, {tmp_path / 'c.bom.csv'}, "
        f"{tmp_path / 'c.order.csv'}, {plot}"
    ) in out
    assert netlist.exists() and plot.exists()
    main([*argv, "--json"])
    captured = capsys.readouterr()
    json.loads(captured.out)  # nothing but the object
    assert f"wrote {netlist}" in captured.err
