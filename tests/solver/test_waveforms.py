"""Waveforms: lookup by SPICE name, interpolation, CSV/NPZ round trips."""

import numpy as np
import pytest

from circuitsim.solver.waveforms import Waveforms


def _ramp() -> Waveforms:
    t = np.linspace(0.0, 1.0, 11)
    return Waveforms(time=t, signals={"v(out)": 2.0 * t, "i(v1)": -t})


def test_lookup_by_node_or_spice_name():
    w = _ramp()
    assert w["OUT"] is w["v(out)"]
    assert "out" in w and "i(V1)" in w and "nope" not in w
    with pytest.raises(KeyError, match="no signal"):
        w["nope"]


def test_interpolation_is_exact_on_a_linear_signal():
    w = _ramp().at(np.array([0.05, 0.55]))
    np.testing.assert_allclose(w["out"], [0.1, 1.1], rtol=0, atol=1e-15)


def test_csv_and_npz_round_trip(tmp_path):
    w = _ramp()
    w.to_csv(tmp_path / "w.csv")
    back = Waveforms.from_csv(tmp_path / "w.csv")
    assert back.names == ["v(out)", "i(v1)"]
    np.testing.assert_array_equal(back["i(v1)"], w["i(v1)"])
    assert (tmp_path / "w.csv").read_text().splitlines()[0] == "time,v(out),i(v1)"
    w.to_npz(tmp_path / "w.npz")
    with np.load(tmp_path / "w.npz") as data:
        np.testing.assert_array_equal(data["v(out)"], w["v(out)"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.csv", "w.npz"]
