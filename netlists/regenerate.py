"""Regenerate the committed paper netlists: ``python netlists/regenerate.py``.

Writes every case of :mod:`circuitsim.synthesis.paper` into this folder (netlist, scale file,
bill of materials) and prints each mapping check.
tests/synthesis/test_synthesis_generate_cli.py fails when the files here differ from what the
generator produces now.
"""

from pathlib import Path

from circuitsim.synthesis.paper import paper_netlists

if __name__ == "__main__":
    for result in paper_netlists(Path(__file__).resolve().parent):
        print(result.netlist.name, "-", result.report.summary().splitlines()[0])
        for warning in result.warnings:
            print("  warning:", warning)
