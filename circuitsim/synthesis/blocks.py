"""Small building blocks shared by the translator: rounding a resistor, summers, switches.

Every resistor the translator places goes through :func:`place_resistor`, which rounds it to
the chosen series and records a bill-of-materials line with the coefficient it was meant to
set and the one it sets after rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from circuitsim.netlist.circuit import Circuit, Resistor
from circuitsim.synthesis.eseries import (
    parallel_pair,
    parallel_value,
    round_to_series,
    series_pair,
)
from circuitsim.synthesis.opamps import add_opamp


@dataclass(frozen=True)
class BomEntry:
    """One line of the bill of materials.

    Attributes
    ----------
    part : str
        Element name (``"R31"``, ``"C3"``).
    value : float
        Ohms or farads.
    unit : str
        ``"ohm"`` or ``"F"``.
    series : str
        ``"E96"``, ``"E24"``, ``"exact"`` (resistors) or ``"decade"`` (capacitors).
    role : str
        What the part does, in words (``"y -> y_dot integrator (A[y_dot, y])"``).
    target : float
        The coefficient the part was meant to set (model units; 1/s for A entries), NaN for
        parts that set none (capacitors, inverter pairs).
    realized : float
        The coefficient set with the rounded value.
    nominal : float
        A potentiometer's full resistance (ohms; ``value`` is its setting), NaN for every
        other part.
    """

    part: str
    value: float
    unit: str
    series: str
    role: str
    target: float = math.nan
    realized: float = math.nan
    nominal: float = math.nan

    @property
    def error(self) -> float:
        """Relative coefficient error realized/target - 1 (NaN when no coefficient)."""
        if math.isnan(self.target) or self.target == 0:
            return math.nan
        return self.realized / self.target - 1.0


class Builder:
    """A circuit under construction plus its bill of materials."""

    def __init__(
        self,
        circuit: Circuit,
        series: str,
        opamp_kind: str,
        pair_tolerance: float = math.inf,
        part_range: tuple[float, float] = (0.0, math.inf),
    ) -> None:
        self.circuit = circuit
        self.series = series
        self.opamp_kind = opamp_kind
        self.pair_tolerance = pair_tolerance  # see SynthesisOptions.pair_tolerance
        # ohms: no series pair for a value outside (refused whole by the buildability
        # check, under its own name), and no part of a pair below the low end
        self.part_range = part_range
        self.bom: list[BomEntry] = []

    @property
    def chain_tolerance(self) -> float:
        """Pair tolerance of the resistors on a nonlinear term's path (its summers and its
        switched resistor): a coefficient there is the product of up to four rounded
        resistors (argument summer, term summer, inverter, switched resistor), and the terms
        into one state may partly cancel (quarter_car: constants -404 and +1000 into zu_dot
        amplify the errors by 1.7), so each gets a quarter of the tolerance."""
        return self.pair_tolerance / 4

    def place_resistor(
        self,
        name: str,
        node_a: str,
        node_b: str,
        ideal: float,
        role: str,
        target: float = math.nan,
        series_extra: float = 0.0,
        series: str | None = None,
        parallel: bool = False,
        pair_tolerance: float | None = None,
    ) -> float:
        """Add a resistor whose ideal value is ``ideal`` ohms (total, including
        ``series_extra``, e.g. a switch's on resistance); returns the realized total.

        The coefficient it sets is taken as proportional to 1/R: realized =
        target * ideal / (rounded + series_extra). A resistor that sets a coefficient
        (``target`` given) and that one standard value misses by more than the pair tolerance
        becomes a series pair ``{name}A`` (node_a side) + ``{name}B`` with the internal node
        ``{name}_mid`` (:func:`~circuitsim.synthesis.eseries.series_pair`); the A line of the
        bill of materials carries the pair's coefficient. With ``parallel`` (a resistor whose
        two nodes take a second one, i.e. no switch in its path), a pair that still misses the
        tolerance is compared with the best parallel pair ``{name}A`` || ``{name}B``
        (:func:`~circuitsim.synthesis.eseries.parallel_pair`), and the closer one is used.
        ``pair_tolerance`` replaces the builder's (e.g. :attr:`chain_tolerance`).
        """
        tolerance = self.pair_tolerance if pair_tolerance is None else pair_tolerance
        chosen = series or self.series
        wanted = max(ideal - series_extra, 1e-3)
        low, high = self.part_range
        if math.isnan(target) or not low <= wanted <= high:
            values: tuple[float, ...] = (round_to_series(wanted, chosen),)
        else:
            values = series_pair(wanted, chosen, tolerance, low)
        values, kind = self._with_parallel(values, wanted, chosen, parallel, tolerance)
        combined = parallel_value(values) if kind == "parallel" else sum(values)
        total = combined + series_extra
        realized = float(target * ideal / total) if not math.isnan(target) else math.nan
        if len(values) == 1:
            self.circuit.add(Resistor(name, node_a, node_b, values[0]))
            self.bom.append(
                BomEntry(name, values[0], "ohm", chosen, role, float(target), realized)
            )
            return total
        first, second = f"{name}A", f"{name}B"
        # series: through the internal node {name}_mid; parallel: both between the nodes
        middle = f"{name.lower()}_mid" if kind == "series" else node_b
        self.circuit.add(Resistor(first, node_a, middle, values[0]))
        self.circuit.add(Resistor(second, middle if kind == "series" else node_a, node_b,
                                  values[1]))  # fmt: skip
        self.bom.append(
            BomEntry(first, values[0], "ohm", chosen, f"{role}; {kind} pair with {second}",
                     float(target), realized)
        )  # fmt: skip
        self.bom.append(
            BomEntry(second, values[1], "ohm", chosen, f"{role}; {kind} pair with {first}")
        )
        return total

    def _with_parallel(
        self, values, wanted, chosen, parallel, tolerance
    ) -> tuple[tuple[float, ...], str]:
        """``values`` (one part or a series pair), or the parallel pair where allowed and closer."""
        if parallel and len(values) == 2 and abs(sum(values) / wanted - 1) > tolerance:
            pair = parallel_pair(wanted, chosen, self.part_range[0])
            if pair is not None and abs(parallel_value(pair) / wanted - 1) < abs(
                sum(values) / wanted - 1
            ):
                return pair, "parallel"
        return values, "series"

    def summer(
        self,
        opamp: str,
        prefix: str,
        output: str,
        inputs: list[tuple[str, str, float, float, str]],
        r_feedback: float,
        pair_tolerance: float | None = None,
    ) -> None:
        """Inverting summer: v(output) = -sum_k w_k v(node_k).

        ``inputs`` holds (suffix, node, weight w_k > 0, target coefficient, role); the input
        resistor R{prefix}_{suffix} = r_feedback / w_k is rounded to the series, the feedback
        resistor R{prefix}_F is r_feedback exactly (a standard value). ``pair_tolerance``: as
        in :meth:`place_resistor`.
        """
        junction = f"{prefix.lower()}_j"
        for suffix, node, weight, target, role in inputs:
            self.place_resistor(
                f"R{prefix}_{suffix}", node, junction, r_feedback / weight, role, target,
                pair_tolerance=pair_tolerance,
            )
        self.circuit.add(Resistor(f"R{prefix}_F", junction, output, r_feedback))
        self.bom.append(
            BomEntry(f"R{prefix}_F", r_feedback, "ohm", "exact", f"feedback of summer {prefix}")
        )
        add_opamp(self.circuit, f"X{prefix}", "0", junction, output, self.opamp_kind)
