"""Generate the three files of a circuit: ``FILE.cir``, ``FILE.scale.json``, ``FILE.bom.csv``.

The netlist is written in the chosen dialect, then read back from disk and checked against the
model (:func:`~circuitsim.synthesis.check.check_mapping`), so what is reported is what the file
realizes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

from circuitsim.mechanics.system import System
from circuitsim.netlist.writer import save_netlist
from circuitsim.synthesis.bom import save_bom
from circuitsim.synthesis.check import MappingReport, check_mapping
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.translator import Synthesis, synthesize


@dataclass
class Generated:
    """The synthesis, the files written and the mapping check of the written netlist."""

    synthesis: Synthesis
    netlist: Path
    scale_file: Path
    bom_file: Path
    report: MappingReport

    @property
    def warnings(self) -> list[str]:
        """Translator warnings followed by the check's."""
        return self.synthesis.warnings + self.report.warnings


def companion_paths(netlist: str | os.PathLike) -> tuple[Path, Path]:
    """``FILE.scale.json`` and ``FILE.bom.csv`` for ``FILE.cir`` (any suffix is replaced)."""
    stem = Path(netlist).with_suffix("")
    return Path(f"{stem}.scale.json"), Path(f"{stem}.bom.csv")


def switch_at(system: System, t_on: float | None) -> System:
    """``system`` with every piecewise-linear term switched in at model time ``t_on`` (s)."""
    if t_on is None:
        return system
    terms = tuple(replace(term, t_on=t_on) for term in system.nonlinear)
    return replace(system, nonlinear=terms)


def generate(
    system: System,
    path: str | os.PathLike,
    options: SynthesisOptions | None = None,
    dialect: str = "ngspice",
) -> Generated:
    """Translate ``system``, write the netlist, scale file and BOM, and check the netlist.

    Parameters
    ----------
    system : System
    path : path-like
        The netlist file (``.cir``); the scale file and BOM are written beside it.
    options : SynthesisOptions, optional
    dialect : str
        ``ngspice``, ``ltspice`` or ``multisim``.

    Returns
    -------
    Generated
    """
    synthesis = synthesize(system, options)
    netlist = Path(path)
    scale_file, bom_file = companion_paths(netlist)
    save_netlist(synthesis.circuit, netlist, dialect)
    synthesis.scale_map.save(scale_file)
    save_bom(synthesis.bom, bom_file)
    report = check_mapping(netlist, scale_file, system, bom=bom_file)
    return Generated(synthesis, netlist, scale_file, bom_file, report)
