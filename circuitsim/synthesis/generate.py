"""Generate the files of a circuit: ``FILE.cir``, ``FILE.scale.json``, ``FILE.bom.csv`` (every
part) and ``FILE.order.csv`` (what to order, grouped); with a knob (:mod:`~circuitsim.synthesis.
knob`) also ``FILE.knob.csv``, the dial tables, and on request a schematic (SVG or PNG).

The three texts are rendered first (the netlist in the chosen dialect), then parsed back exactly
as a reader of the files would parse them and checked against the model
(:func:`~circuitsim.synthesis.check.check_mapping`), so what is reported is what the files
realize. Only then are they written, all or nothing
(:func:`~circuitsim.atomic.write_files_atomic`): a failure anywhere - a bad output path, a
netlist that does not read back, a folder in place of a companion file - leaves every existing
file as it was, never a new netlist beside an old bill of materials.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

from circuitsim.atomic import check_writable, write_files_atomic
from circuitsim.mechanics.system import System
from circuitsim.netlist.reader import NetlistWarning, parse_netlist
from circuitsim.netlist.writer import write_netlist
from circuitsim.synthesis.bom import bom_text, order_text, parse_bom
from circuitsim.synthesis.check import MappingReport, check_mapping
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.knob import Knob, KnobRequest, add_knobs, knob_table_text
from circuitsim.synthesis.offsets import offset_warning
from circuitsim.synthesis.options import SynthesisOptions
from circuitsim.synthesis.scalemap import ScaleMap
from circuitsim.synthesis.schematic import schematic_format, schematic_image
from circuitsim.synthesis.translator import Synthesis, synthesize


@dataclass
class Generated:
    """The synthesis, the files written and the mapping check of the written netlist."""

    synthesis: Synthesis
    netlist: Path
    scale_file: Path
    bom_file: Path
    report: MappingReport
    order_file: Path | None = None
    knobs: list[Knob] = field(default_factory=list)
    knob_file: Path | None = None
    schematic_file: Path | None = None
    kicad_file: Path | None = None
    kicad_library: Path | None = None

    @property
    def warnings(self) -> list[str]:
        """Translator warnings followed by the check's."""
        return self.synthesis.warnings + self.report.warnings


def companion_paths(netlist: str | os.PathLike) -> tuple[Path, Path, Path]:
    """``FILE.scale.json``, ``FILE.bom.csv`` and ``FILE.order.csv`` for ``FILE.cir`` (any
    suffix is replaced)."""
    stem = Path(netlist).with_suffix("")
    return Path(f"{stem}.scale.json"), Path(f"{stem}.bom.csv"), Path(f"{stem}.order.csv")


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
    knob: KnobRequest | None = None,
    schematic: str | os.PathLike | None = None,
    kicad: str | os.PathLike | None = None,
) -> Generated:
    """Translate ``system``, check the circuit, and write the netlist, scale file and BOMs.

    The files are written only if everything before succeeded, and then all together: on any
    error no file has changed. A mapping check that finds mismatches is not an error: the files
    are written and ``report`` lists the mismatches.

    Parameters
    ----------
    system : System
        The model to realize.
    path : path-like
        The netlist file (``.cir``); the scale file and both BOMs are written beside it (see
        :func:`companion_paths`).
    options : SynthesisOptions, optional
        Translator options (op-amp model, scaling, resistor series ...).
    dialect : str
        ``ngspice``, ``ltspice`` or ``multisim``.
    knob : KnobRequest, optional
        Turn the resistors that follow ``knob.parameter`` into a fixed part plus a
        potentiometer set for the system's value of it, and write the dial tables to
        ``FILE.knob.csv``.
    schematic : path-like, optional
        Also draw the circuit (:mod:`~circuitsim.synthesis.schematic`) into this ``.svg`` or
        ``.png`` file, written with the others.
    kicad : path-like, optional
        Also write a KiCad schematic ``FILE.kicad_sch`` and its SPICE library
        ``FILE.spice.lib`` (:mod:`~circuitsim.synthesis.kicad`).

    Returns
    -------
    Generated

    Raises
    ------
    OSError
        A :class:`~circuitsim.atomic.WriteError` naming the file that cannot be written (a
        missing folder, a folder in its place, no permission), raised before the translation.
    SynthesisError, NetlistError
        The model cannot be translated, or the netlist does not read back.
    """
    # The output paths first: a bad one fails at once, not after the translation.
    check_writable(path)
    netlist = Path(path)
    scale_file, bom_file, order_file = companion_paths(netlist)
    for companion in (scale_file, bom_file, order_file):
        check_writable(companion)
    knob_file = Path(f"{netlist.with_suffix('')}.knob.csv") if knob is not None else None
    if knob_file is not None:
        check_writable(knob_file)
    if schematic is not None:
        schematic_format(schematic)
        check_writable(schematic)
    kicad_library = None
    if kicad is not None:
        # kiutils is imported only when a KiCad schematic is asked for
        from circuitsim.synthesis.kicad import check_kicad_path, kicad_library_path

        check_kicad_path(kicad)
        kicad_library = kicad_library_path(kicad)
        check_writable(kicad)
        check_writable(kicad_library)
    synthesis = synthesize(system, options)
    offsets = offset_warning(synthesis, system)
    if offsets is not None:
        synthesis.warnings.append(offsets)
    knobs = []
    if knob is not None:
        if knob.parameter not in system.parameters:
            raise SynthesisError(f"the knob's parameter {knob.parameter!r} is not the model's")
        series = (options or SynthesisOptions()).series_key
        value = float(system.parameters[knob.parameter])
        knobs = add_knobs(synthesis.circuit, synthesis.bom, system, knob, series, value)
    # The state nodes saved (and printed, for ngspice -b and gnucap), subcircuit defaults no
    # instance changes folded in, and no capacitor IC= when every .ic value is 0: the netlist
    # runs as it is in batch mode, in gnucap and through PySpice's parser (which refuses IC=).
    # A nonzero start keeps its IC=: gnucap ignores .ic and would start at 0 V.
    state_nodes = [state.node for state in synthesis.scale_map.states.values()]
    starts = synthesis.circuit.initial_conditions.values()
    texts = {
        netlist: write_netlist(
            synthesis.circuit,
            dialect,
            outputs=state_nodes,
            drop_implied_ic=all(value == 0 for value in starts),
            fold_subcircuit_defaults=True,
        ),
        scale_file: synthesis.scale_map.to_text(),
        bom_file: bom_text(synthesis.circuit, synthesis.bom),
        order_file: order_text(synthesis.circuit, synthesis.bom),
    }
    # Parsed from the very texts the files will hold, as read_netlist and the loaders would
    # (same names in messages, includes looked up beside the netlist): nothing of the
    # generator's memory enters the check, and nothing is on disk if the texts are unreadable.
    with warnings.catch_warnings():
        # the .save/.print lines written above, which the reader passes over with a warning
        warnings.filterwarnings("ignore", r".*\.(save|print) ignored", NetlistWarning)
        circuit = parse_netlist(
            texts[netlist], source=str(netlist), base_dir=str(netlist.resolve().parent)
        )
    scale_map = ScaleMap.from_text(texts[scale_file], source=str(scale_file))
    bom = parse_bom(texts[bom_file], source=str(bom_file))
    report = check_mapping(circuit, scale_map, system, bom=bom)
    if knob_file is not None:
        texts[knob_file] = knob_table_text(knobs, knob)
    if schematic is not None:
        texts[Path(schematic)] = schematic_image(
            circuit, schematic_format(schematic), list(system.states), synthesis.bom
        )
    if kicad is not None:
        from circuitsim.synthesis.kicad import kicad_schematic_text
        from circuitsim.synthesis.kicad_spice import spice_library_text

        texts[Path(kicad)] = kicad_schematic_text(
            circuit, list(system.states), synthesis.bom, kicad_library.name
        )
        texts[kicad_library] = spice_library_text(circuit)
    write_files_atomic(texts)
    return Generated(
        synthesis, netlist, scale_file, bom_file, report, order_file, knobs, knob_file,
        None if schematic is None else Path(schematic),
        None if kicad is None else Path(kicad), kicad_library,
    )  # fmt: skip
