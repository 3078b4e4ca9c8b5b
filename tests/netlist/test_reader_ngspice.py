"""ngspice as the referee: the corpus is valid SPICE, and ``gnd`` is ground as the reader says."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from circuitsim.netlist.reader import parse_netlist

CORPUS = Path(__file__).parent / "corpus"
requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)


def ngspice(path: Path) -> str:
    result = subprocess.run(
        ["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=120, cwd=path.parent
    )
    return result.stdout + result.stderr


@requires_ngspice
@pytest.mark.parametrize("path", sorted(CORPUS.glob("*.cir")), ids=lambda p: p.name)
def test_corpus_runs_in_ngspice_without_errors(path):
    log = ngspice(path)
    bad = [
        line
        for line in log.splitlines()
        if re.search(r"\b(error|warning|unknown|fatal)\b", line, re.IGNORECASE)
    ]
    assert not bad, "\n".join(bad)
    assert "Circuit:" in log  # ngspice did read it


@requires_ngspice
def test_gnd_is_ground_in_ngspice_and_in_the_reader(tmp_path):
    text = "gnd alias\nV1 a gnd DC 1\nR1 a gnd 1k\nR2 a 0 1k\n.op\n.end\n"
    path = tmp_path / "gnd.cir"
    path.write_text(text)
    log = ngspice(path)
    # both resistors carry 1 mA only if gnd and 0 are the same node
    current = float(re.search(r"v1#branch\s+([-+0-9.e]+)", log)[1])
    assert current == pytest.approx(-2e-3, rel=1e-6)
    circuit = parse_netlist(text)
    assert [e.negative for e in circuit.elements] == ["0", "0", "0"]
