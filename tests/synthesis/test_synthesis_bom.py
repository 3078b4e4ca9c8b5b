"""The bill of materials: every part of the generated circuit and a grouped order view.

The counts are checked against the netlist as written and read back (an independent count of
its elements), not against the BOM code's own walk of the circuit.
"""

import csv
import math
import re
from pathlib import Path

import pytest

from circuitsim.mechanics import load_model
from circuitsim.netlist.circuit import Diode, SubcircuitCall, Switch, VoltageSource
from circuitsim.netlist.reader import read_netlist
from circuitsim.synthesis.generate import generate
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.parts import _pack_sections, series_label

MODELS = Path(__file__).parent / "models"
SOURCE_KINDS = {"supply rail", "reference voltage", "switch control", "signal generator"}


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _generated(tmp_path, system, opamp="tl074", **options):
    result = generate(system, tmp_path / "c.cir", SynthesisOptions(opamp=opamp, **options))
    assert result.order_file == tmp_path / "c.order.csv"
    circuit = read_netlist(result.netlist)
    return circuit, _rows(result.bom_file), _rows(result.order_file)


def _wheelset():
    return load_model().system(parameters={"V": 55.0, "f": 3.0, "a": 0.040})


def _check_counts(circuit, parts, order, opamp_subckt):
    """Every element is one per-part row; the order rows account for each exactly once."""
    assert sorted(p["part"] for p in parts) == sorted(e.name for e in circuit.elements)
    sections = [
        e.name for e in circuit.elements
        if isinstance(e, SubcircuitCall) and e.subcircuit.upper() == opamp_subckt
    ]  # fmt: skip
    placed = {p["part"]: p["designator"] for p in parts if p["kind"] == "op-amp section"}
    assert sorted(placed) == sorted(sections)
    assert len(set(placed.values())) == len(sections)  # each place used once
    assert all(re.fullmatch(r"U\d+[A-D]", d) for d in placed.values())
    packages = {d[:-1] for d in placed.values()}
    assert len(packages) == math.ceil(len(sections) / 4)
    opamp_rows = [o for o in order if "op-amp" in o["description"]]
    assert sum(int(o["quantity"]) for o in opamp_rows) == len(packages)
    assert {u for o in opamp_rows for u in o["designators"].split()} == packages
    by_kind = {}
    for p in parts:
        by_kind.setdefault(p["kind"], []).append(p["designator"])
    counted = {  # independent: element classes of the netlist read back
        "diode": sum(isinstance(e, Diode) for e in circuit.elements),
        "switch": sum(isinstance(e, Switch) for e in circuit.elements),
        "source": sum(isinstance(e, VoltageSource) for e in circuit.elements),
    }
    assert len(by_kind.get("diode", [])) == counted["diode"]
    assert len(by_kind.get("switch", [])) == counted["switch"]
    assert sum(len(by_kind.get(k, [])) for k in SOURCE_KINDS) == counted["source"]
    # quantities in the order file sum to the per-part rows, designators listed once each
    others = [o for o in order if o not in opamp_rows]
    listed = [d for o in others for d in o["designators"].split()]
    assert sum(int(o["quantity"]) for o in others) == len(parts) - len(sections) == len(listed)
    assert sorted(listed) == sorted(p["designator"] for p in parts if p["part"] not in placed)
    return counted


def test_wheelset_tl074_packages_and_counts(tmp_path):
    circuit, parts, order = _generated(tmp_path, _wheelset())
    counted = _check_counts(circuit, parts, order, "TL074")
    assert counted == {"diode": 4, "switch": 1, "source": 6}  # 2 |x| blocks; S1; see below
    placed = {p["part"]: p["designator"] for p in parts if p["kind"] == "op-amp section"}
    assert len(placed) == 13 and placed["XU1A"] == "U1A" and placed["XU2D"] == "U2D"
    # the paper's U1/U2 are full, so the flange's five sections go into U3 and U4
    assert {placed[n] for n in placed if not n.startswith("XU")} == {
        "U3A", "U3B", "U3C", "U3D", "U4A"
    }  # fmt: skip
    (opamps,) = [o for o in order if "op-amp" in o["description"]]
    assert opamps["description"] == "TL074 quad op-amp" and opamps["quantity"] == "4"
    rows = {o["designators"]: o for o in order}
    assert rows["VCC"]["value"] == "+15 V" and rows["VEE"]["value"] == "-15 V"
    assert float(circuit.element("VCC").dc) == 15.0  # the rail the netlist uses
    assert rows["S1"]["description"] == "SPST toggle switch" and "SW_FLANGE" in rows["S1"]["note"]
    (diodes,) = [o for o in order if "diode" in o["description"]]
    assert diodes["description"].startswith("1N4148") and "D1N4148" in diodes["note"]
    kinds = {p["part"]: p["kind"] for p in parts}
    assert kinds["VXFG1"] == "signal generator" and kinds["VFLANGE_CTL"] == "switch control"
    assert kinds["VFLANGE_ABS1_B"] == kinds["VFLANGE_ABS2_B"] == "reference voltage"


def test_series_labels_and_coefficient_columns(tmp_path):
    # one rounded value per coefficient (no series pairs): R1 is a single 30.1 kOhm
    circuit, parts, order = _generated(tmp_path, _wheelset(), pair_tolerance=math.inf)
    rows = {p["part"]: p for p in parts}
    assert rows["RI1A"]["series"] == "E24"  # 10 kOhm is standard, not "exact"
    assert rows["RFLANGE_ABS1_4"]["series"] == "exact"  # 5 kOhm is in neither series
    assert rows["R1"]["series"] == "E96" and rows["R1"]["value"] == "30100.0"
    target, realized = float(rows["R1"]["target"]), float(rows["R1"]["realized"])
    assert float(rows["R1"]["error"]) == pytest.approx(realized / target - 1, rel=1e-12)
    assert rows["C1"]["series"] == "E6"
    by_value = {o["value"]: o for o in order}
    assert by_value["5 kOhm"]["series"] == "exact" and "in parallel" in by_value["5 kOhm"]["note"]
    assert by_value["10 kOhm"]["series"] == "E24" and by_value["30.1 kOhm"]["series"] == "E96"
    assert series_label(30100, "resistor") == "E96" and series_label(5000, "resistor") == "exact"
    assert series_label(4.7e-9, "capacitor") == "E6" and series_label(3.9e-6, "capacitor") == "E12"


def test_series_pairs_in_the_bom(tmp_path):
    """With pairs (the default), R1 = 30.1 kOhm (0.3 % off) becomes R1A + R1B; the A row
    carries the pair's coefficient, the B row none, both say so."""
    circuit, parts, order = _generated(tmp_path, _wheelset())
    rows = {p["part"]: p for p in parts}
    assert "R1" not in rows and {"R1A", "R1B"} <= set(rows)
    first, second = rows["R1A"], rows["R1B"]
    assert "series pair with R1B" in first["role"] and "series pair with R1A" in second["role"]
    assert series_label(float(first["value"]), "resistor") in ("E24", "E96")
    assert series_label(float(second["value"]), "resistor") in ("E24", "E96")
    assert abs(float(first["error"])) <= 1e-3 and second["target"] == second["error"] == ""
    # the written netlist has them in series through their own node
    elements = {e.name.upper(): e for e in circuit.elements}
    a, b = elements["R1A"], elements["R1B"]
    assert set(a.nodes) & set(b.nodes) == {"r1_mid"}
    _check_counts(circuit, parts, order, "TL074")


def test_ideal_opamps_propose_a_real_quad(tmp_path):
    circuit, parts, order = _generated(tmp_path, _wheelset(), opamp="ideal")
    _check_counts(circuit, parts, order, "OPAMP_IDEAL")
    (opamps,) = [o for o in order if "op-amp" in o["description"]]
    assert opamps["description"] == "TL074 quad op-amp"
    assert "ideal op-amp model OPAMP_IDEAL" in opamps["note"] and "supplies" in opamps["note"]
    assert not [p for p in parts if p["kind"] == "supply rail"]  # the ideal netlist has none


@pytest.mark.parametrize("name", ["two_mass_stop", "chua_diode"])
def test_other_models(tmp_path, name):
    system = load_model(MODELS / f"{name}.toml").system()
    circuit, parts, order = _generated(tmp_path, system, series="E24")
    counted = _check_counts(circuit, parts, order, "TL074")
    assert counted["diode"] > 0 and counted["source"] >= 2  # |x| diodes; the +/-15 V rails


def test_sections_fill_the_named_packages_first():
    placed = _pack_sections(["XU1A", "XU1B", "XFOO", "XBAR", "XBAZ"])
    assert placed == {"XU1A": "U1A", "XU1B": "U1B", "XFOO": "U1C", "XBAR": "U1D", "XBAZ": "U2A"}


def test_a_folder_in_place_of_the_order_file_writes_nothing(tmp_path):
    (tmp_path / "c.order.csv").mkdir()
    with pytest.raises(OSError, match="c.order.csv"):
        generate(_wheelset(), tmp_path / "c.cir")
    assert [p.name for p in tmp_path.iterdir()] == ["c.order.csv"]


def test_older_bom_files_still_read(tmp_path):
    from circuitsim.synthesis.bom import parse_bom
    from circuitsim.synthesis.errors import SynthesisError

    old = "part,value,unit,series,role,target,realized,error\nR1,30100.0,ohm,E96,x,1.0,1.01,0.01\n"
    (entry,) = parse_bom(old)
    assert entry.part == "R1" and entry.error == pytest.approx(0.01)
    with pytest.raises(SynthesisError, match=r"b.csv:1: expected the header"):
        parse_bom("part,value\n", source="b.csv")
