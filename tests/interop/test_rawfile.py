"""Rawfiles: ngspice's binary and ASCII writings of one run agree; damaged files raise."""

import shutil
import struct
import subprocess

import numpy as np
import pytest

from circuitsim.interop.errors import NgspiceError
from circuitsim.interop.rawfile import parse_ascii_raw, parse_rawfile

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def _binary(names_kinds, rows, flags="real", plot="Transient Analysis") -> bytes:
    header = (
        f"Title: t\nDate: d\nPlotname: {plot}\nFlags: {flags}\n"
        f"No. Variables: {len(names_kinds)}\nNo. Points: {len(rows)}\nVariables:\n"
        + "".join(f"\t{i}\t{n}\t{k}\n" for i, (n, k) in enumerate(names_kinds))
        + "Binary:\n"
    )
    flat = [x for row in rows for x in row]
    return header.encode() + struct.pack(f"<{len(flat)}d", *flat)


def test_binary_by_hand():
    data = _binary(
        [("time", "time"), ("out", "voltage"), ("l1#branch", "current")],
        [(0.0, 1.0 / 3.0, -1e-3), (1e-3, 0.1 + 0.2, 2e-3)],
    )
    waves = parse_rawfile(data)
    assert waves.time.tolist() == [0.0, 1e-3]
    # Binary values are the doubles themselves, bit for bit.
    assert waves.signals["v(out)"].tolist() == [1.0 / 3.0, 0.1 + 0.2]
    assert waves.signals["i(l1)"].tolist() == [-1e-3, 2e-3]
    with pytest.raises(NgspiceError, match="cut short: expected 2 points of 3 values"):
        parse_rawfile(data[:-8])
    with pytest.raises(NgspiceError, match="not an ngspice rawfile"):
        parse_rawfile(b"hello")


def test_binary_complex_by_hand():
    rows = [(10.0, 0.0, 0.0, 2.0), (100.0, 0.0, -1.0, 0.0)]  # frequency, then v(out) re, im
    waves = parse_rawfile(
        _binary([("frequency", "frequency"), ("v(out)", "voltage")], rows, "complex", "AC Analysis")
    )
    assert waves.time.tolist() == [10.0, 100.0]
    assert waves.signals["vm(out)"].tolist() == [2.0, 1.0]
    assert waves.signals["vp(out)"].tolist() == [90.0, 180.0]


def test_operating_point_has_one_point_at_zero():
    data = _binary([("v(a)", "voltage")], [(2.5,)], plot="Operating Point")
    waves = parse_rawfile(data)
    assert waves.time.tolist() == [0.0] and waves.signals["v(a)"].tolist() == [2.5]


@requires_ngspice
@pytest.mark.ngspice
def test_binary_and_ascii_of_one_ngspice_run_agree(tmp_path):
    deck = tmp_path / "deck.cir"
    deck.write_text(
        "rc\nV1 in 0 SIN(0 1 1k)\nR1 in out 1k\nC1 out 0 100n\n.tran 10u 2m\n"
        f".control\nrun\nset filetype=binary\nwrite {tmp_path}/b.raw\n"
        f"set filetype=ascii\nwrite {tmp_path}/a.raw\n.endc\n.end\n"
    )
    subprocess.run(["ngspice", "-b", str(deck)], capture_output=True, check=False, timeout=60)
    binary = parse_rawfile((tmp_path / "b.raw").read_bytes())
    ascii_ = parse_ascii_raw((tmp_path / "a.raw").read_text())
    assert binary.names == ascii_.names == ["v(in)", "v(out)", "i(v1)"]
    assert len(binary.time) > 100
    # ASCII carries 16 significant digits: agreement to that, not beyond.
    assert np.allclose(binary.time, ascii_.time, rtol=1e-15, atol=0)
    for name in binary.names:
        assert np.allclose(binary[name], ascii_[name], rtol=1e-15, atol=1e-300)
