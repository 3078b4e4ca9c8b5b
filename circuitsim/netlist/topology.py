"""Topology checks: what makes a circuit unsolvable or suspicious before any engine runs.

:func:`check_circuit` returns a list of :class:`Finding` and never raises for a bad circuit
(only for a malformed object). It works on a hierarchical circuit (checks each ``.subckt``
body, then flattens for the electrical checks) and on a flat one (the solver calls it to
explain a singular matrix); it needs no analysis and only touches the graph once.

Kinds of finding
----------------
``duplicate-name``
    Two elements of one scope (top level or one ``.subckt`` body) share a name, ignoring case.
``undefined-model`` / ``wrong-model-kind``
    A diode, switch, JFET or BJT names a model that no enclosing scope defines, or one of
    another kind (a diode needs ``D``, a switch ``SW``, a JFET ``NJF``/``PJF``, a BJT
    ``NPN``/``PNP``).
``undefined-subcircuit`` / ``port-count``
    An ``X`` line names no known ``.subckt``, or passes another number of nodes than it has
    ports.
``undefined-control``
    An ``F``/``H`` source names a controlling voltage source that its scope does not have.
``unconnected-port``
    A ``.subckt`` port that no element inside it touches.
``undefined-parameter`` / ``bad-expression``
    A value (element field, ``.param``, instance or model parameter, ``.ic``, option) names a
    parameter that no scope defines, or cannot be evaluated (division by zero, square root of
    a negative number, a result beyond the float range ...). Values that fail only because
    they use such a parameter are not reported again.
``zero-resistance``
    A resistor of 0 ohms: the engine stamps conductances and refuses it (ngspice quietly
    makes it 1 milliohm).
``negative-hysteresis``
    A switch model with VH < 0: ngspice runs it with reversed hysteresis, the builtin engine
    with ``|VH|`` (see :func:`negative_hysteresis`); the reader also warns.
``no-nodes``
    The circuit has no node besides ground (an empty or title-only netlist): nothing to
    solve.
``unflattenable``
    Subcircuit expansion failed for a structural reason (recursion, an instance parameter
    the subcircuit does not declare ...) and no other finding explains it.
``floating-node``
    A node with a single terminal on it (the element ends there and carries no current).
``no-dc-path``
    A set of nodes joined to ground by no DC path: only capacitors (or current sources feeding
    capacitors, or controlling inputs) connect it to the rest. Their DC voltages are
    undefined, so ``.op`` and a transient without ``uic`` have a singular matrix.
``current-source-cutset``
    A set of nodes joined to the rest only through current sources (I, G, F outputs): KCL
    fixes the sum of those currents and nothing fixes the voltages, in every analysis.
``voltage-loop``
    A loop made only of voltage sources, E/H outputs and inductors (or one of them with both
    ends on the same node): the loop current is undetermined at DC and KVL may contradict the
    sources.

Why cut sets and DC paths are one computation: take the graph of elements that conduct at DC
(R, L, V, E/H outputs, D, S). A connected piece of it that does not hold ground is exactly a
node set whose only links to the rest are elements left out (C, I, G/F outputs, control
inputs). If those links are all current sources the set is a current-source cut set; if any is
a capacitor it is a capacitor (and current source) cut set, i.e. a node set with no DC path.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass

import networkx as nx

from circuitsim.netlist.circuit import (
    Bjt,
    Capacitor,
    Cccs,
    Ccvs,
    Circuit,
    CurrentControlled,
    CurrentSource,
    Diode,
    Element,
    Inductor,
    Jfet,
    Model,
    PolyCccs,
    PolyCcvs,
    PolyCurrentControlled,
    PolyVccs,
    PolyVcvs,
    PolyVoltageControlled,
    Resistor,
    Subcircuit,
    SubcircuitCall,
    Switch,
    Vccs,
    Vcvs,
    VoltageControlled,
    VoltageSource,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.flatten import ValueProblem, flatten
from circuitsim.netlist.names import fold

GROUND = "0"


@dataclass(frozen=True)
class Finding:
    """One problem found in a circuit.

    Attributes
    ----------
    kind : str
        One of the kinds listed in this module's docstring (``"floating-node"`` ...).
    message : str
        A sentence naming the elements and nodes involved.
    elements : tuple of str
        Element names involved (flattened names for the electrical checks).
    nodes : tuple of str
        Node names involved.
    """

    kind: str
    message: str
    elements: tuple[str, ...] = ()
    nodes: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"{self.kind}: {self.message}"


def check_circuit(circuit: Circuit) -> list[Finding]:
    """All findings for ``circuit``: naming and reference checks per scope, values, electrical.

    Every value is evaluated as :func:`~circuitsim.netlist.flatten.flatten` evaluates it
    (global ``.param`` values, then each instance's parameters), collecting every failure
    instead of stopping at the first. The electrical checks (floating nodes, DC paths, cut
    sets, loops) run on the flattened circuit; if it cannot be flattened (an undefined
    subcircuit, recursion) they run on the top level alone, treating each unresolved ``X``
    call as conducting between all its nodes, so its problems are still reported by the
    reference checks above rather than hidden.
    """
    findings: list[Finding] = []
    _check_scope(
        circuit.elements, [circuit.models], [circuit.subcircuits], "", findings, circuit.elements
    )
    problems: list[ValueProblem] = []
    try:
        flat = flatten(circuit, problems)
        valued = flat.elements
    except NetlistError as exc:
        if not findings:
            findings.append(Finding("unflattenable", str(exc)))
        flat = circuit
        # The top level's own values can still be checked without the calls.
        own = [e for e in circuit.elements if not isinstance(e, SubcircuitCall)]
        problems = []
        try:
            valued = flatten(dataclasses.replace(circuit, elements=own), problems).elements
        except NetlistError:
            valued = []
    findings += [_value_finding(problem) for problem in problems]
    findings += _zero_resistances(valued)
    findings += _hysteresis_findings(flat.models)
    if not any(node != GROUND for element in flat.elements for node in element.nodes):
        findings.append(
            Finding(
                "no-nodes",
                "the circuit has no nodes besides ground (no elements, or all of them on 0): "
                "there is nothing to solve",
            )
        )
    findings += electrical_findings(flat.elements)
    return findings


# --- values ---------------------------------------------------------------------------------


def negative_hysteresis(model: Model) -> str | None:
    """Why a switch model with a negative VH runs differently in the two engines, or None.

    ngspice 39 (``swload.c``) reads VH < 0 as reversed hysteresis: on at VT + VH when the
    control rises, off at VT - VH when it falls (measured with ngspice -b: VT=0.5, VH=-0.2 on
    at 0.3 V and off at 0.7 V). The builtin engine uses ``|VH|`` as ordinary hysteresis (on at
    0.7 V, off at 0.3 V). An expression for VH is not evaluated here (see check_circuit).
    """
    vh = model.params.get("vh")
    if fold(model.kind) != "sw" or not isinstance(vh, float | int) or not vh < 0:
        return None
    vt = model.params.get("vt", 0.0)
    vt = float(vt) if isinstance(vt, float | int) else math.nan
    return (
        f"switch model {model.name}: VH={vh:g} is negative; ngspice turns such a switch on at "
        f"VT+VH={vt + vh:g} V when the control rises and off at VT-VH={vt - vh:g} V when it "
        f"falls (reversed hysteresis), the builtin engine uses |VH| (on at {vt - vh:g} V, off "
        f"at {vt + vh:g} V): the engines differ; write VH >= 0"
    )


def _hysteresis_findings(models: Mapping[str, Model]) -> list[Finding]:
    return [
        Finding("negative-hysteresis", problem)
        for model in models.values()
        if (problem := negative_hysteresis(model))
    ]


def _value_finding(problem: ValueProblem) -> Finding:
    kind = "undefined-parameter" if problem.undefined is not None else "bad-expression"
    elements = (problem.element,) if problem.element is not None else ()
    return Finding(kind, str(problem), elements)


def _zero_resistances(elements: list[Element]) -> list[Finding]:
    """Resistors of exactly 0 ohms (after evaluation) among flat elements."""
    return [
        Finding(
            "zero-resistance",
            f"{e.name}: resistance 0 is not allowed (join nodes {e.positive} and {e.negative} "
            "into one, or put a 0 V source between them to measure the current)",
            (e.name,),
            (e.positive, e.negative),
        )
        for e in elements
        if isinstance(e, Resistor) and isinstance(e.resistance, int | float) and e.resistance == 0
    ]


# --- naming and reference checks, per scope -----------------------------------------------


def _check_scope(
    elements: list[Element],
    models: list[dict[str, Model]],
    subcircuits: list[dict[str, Subcircuit]],
    where: str,
    findings: list[Finding],
    top: list[Element],
) -> None:
    """Checks of one scope's elements; ``models``/``subcircuits`` innermost scope first.

    An F/H control may name a voltage source of its own body or of the top level (as
    :func:`~circuitsim.netlist.flatten.flatten` resolves it).
    """
    scope = f" in .subckt {where}" if where else ""
    seen: dict[str, str] = {}
    for element in elements:
        key = fold(element.name)
        if key in seen:
            findings.append(
                Finding(
                    "duplicate-name",
                    f"{element.name} and {seen[key]} share a name{scope}",
                    (seen[key], element.name),
                )
            )
        else:
            seen[key] = element.name
    for element in elements:
        if isinstance(element, Diode | Switch | Jfet | Bjt):
            _check_model(element, models, scope, findings)
        elif isinstance(element, SubcircuitCall):
            _check_call(element, subcircuits, scope, findings)
        elif isinstance(element, CurrentControlled | PolyCurrentControlled):
            names = (
                element.controls
                if isinstance(element, PolyCurrentControlled)
                else (element.control,)
            )
            for name in names:
                key = fold(name)
                control = next((e for e in [*elements, *top] if fold(e.name) == key), None)
                if not isinstance(control, VoltageSource):
                    what = (
                        "no voltage source"
                        if control is None
                        else f"{control.name}, not a V source"
                    )
                    findings.append(
                        Finding(
                            "undefined-control",
                            f"{element.name} is controlled by {name}: {what}{scope}",
                            (element.name,),
                        )
                    )
    for table in subcircuits[:1]:
        for sub in table.values():
            _check_subcircuit(sub, models, subcircuits, findings, top)


def _check_subcircuit(
    sub: Subcircuit,
    models: list[dict[str, Model]],
    subcircuits: list[dict[str, Subcircuit]],
    findings: list[Finding],
    top: list[Element],
) -> None:
    used = {node for element in sub.elements for node in element.nodes}
    for port in sub.ports:
        if port not in used:
            findings.append(
                Finding(
                    "unconnected-port",
                    f"port {port} of .subckt {sub.name} is connected to nothing inside it",
                    (),
                    (port,),
                )
            )
    _check_scope(
        sub.elements,
        [sub.models, *models],
        [sub.subcircuits, *subcircuits],
        sub.name,
        findings,
        top,
    )


def _lookup(name: str, tables: list[dict]) -> object | None:
    key = fold(name)
    for table in tables:
        for candidate, value in table.items():
            if fold(candidate) == key:
                return value
    return None


_MODEL_KINDS = {Diode: ("D",), Switch: ("SW",), Jfet: ("NJF", "PJF"), Bjt: ("NPN", "PNP")}


def _check_model(
    element: Diode | Switch | Jfet | Bjt,
    models: list[dict[str, Model]],
    scope: str,
    findings: list[Finding],
) -> None:
    kinds = _MODEL_KINDS[type(element)]
    wanted = " or ".join(kinds)
    model = _lookup(element.model, models)
    if model is None:
        findings.append(
            Finding(
                "undefined-model",
                f"{element.name} uses model {element.model!r}, which is not defined{scope}",
                (element.name,),
            )
        )
    elif model.kind.upper() not in kinds:
        findings.append(
            Finding(
                "wrong-model-kind",
                f"{element.name} needs a {wanted} model but {model.name} is "
                f"{model.kind.upper()}{scope}",
                (element.name,),
            )
        )


def _check_call(
    call: SubcircuitCall,
    subcircuits: list[dict[str, Subcircuit]],
    scope: str,
    findings: list[Finding],
) -> None:
    sub = _lookup(call.subcircuit, subcircuits)
    if sub is None:
        findings.append(
            Finding(
                "undefined-subcircuit",
                f"{call.name} calls .subckt {call.subcircuit!r}, which is not defined{scope}",
                (call.name,),
            )
        )
    elif len(call.connections) != len(sub.ports):
        findings.append(
            Finding(
                "port-count",
                f"{call.name} connects {len(call.connections)} nodes to .subckt {sub.name}, "
                f"which has {len(sub.ports)} ports ({' '.join(sub.ports)}){scope}",
                (call.name,),
                tuple(call.connections),
            )
        )


# --- electrical checks, on one flat list of elements -------------------------------------


def _output_nodes(element: Element) -> tuple[str, ...]:
    """The nodes current flows through (controlling inputs excluded)."""
    if isinstance(element, VoltageControlled | PolyVoltageControlled):
        return (element.positive, element.negative)
    return element.nodes


def _conducts_dc(element: Element) -> bool:
    return not isinstance(element, Capacitor | CurrentSource | Vccs | Cccs | PolyVccs | PolyCccs)


def _is_current_source(element: Element) -> bool:
    return isinstance(element, CurrentSource | Vccs | Cccs | PolyVccs | PolyCccs)


def _fixes_voltage(element: Element) -> bool:
    """Elements that force a branch voltage at DC: V, E, H and (a short at DC) L."""
    return isinstance(element, VoltageSource | Vcvs | Ccvs | PolyVcvs | PolyCcvs | Inductor)


def electrical_findings(elements: list[Element]) -> list[Finding]:
    """Floating nodes, no-DC-path sets, current-source cut sets and voltage loops.

    ``elements`` is a flat list (no subcircuit calls expected; a remaining call is treated as
    a conductor between all its nodes). Ground is node ``"0"``.
    """
    findings: list[Finding] = []
    terminals: dict[str, list[str]] = {}
    for element in elements:
        for node in element.nodes:
            terminals.setdefault(node, []).append(element.name)
    floating = [n for n, names in terminals.items() if n != GROUND and len(names) == 1]
    for node in floating:
        findings.append(
            Finding(
                "floating-node",
                f"node {node} has one connection only ({terminals[node][0]})",
                (terminals[node][0],),
                (node,),
            )
        )
    findings += _cut_sets(elements, terminals, set(floating))
    findings += _voltage_loops(elements)
    return findings


def _cut_sets(
    elements: list[Element], terminals: dict[str, list[str]], floating: set[str]
) -> list[Finding]:
    graph = nx.Graph()
    graph.add_nodes_from(terminals)
    graph.add_node(GROUND)
    for element in elements:
        if _conducts_dc(element):
            nodes = _output_nodes(element)
            graph.add_edges_from(zip(nodes[:1] * (len(nodes) - 1), nodes[1:], strict=True))
    pieces = [p for p in nx.connected_components(graph) if GROUND not in p and not p <= floating]
    # The links of each piece: non-conducting branches with one end in it and one outside,
    # gathered in one pass over the elements (linear, however many pieces there are).
    piece_of = {node: index for index, piece in enumerate(pieces) for node in piece}
    links: list[list[Element]] = [[] for _ in pieces]
    for element in elements:
        if _conducts_dc(element):
            continue
        ends = {piece_of.get(n, -1) for n in _output_nodes(element)}
        if len(ends) == 2:
            for index in ends - {-1}:
                links[index].append(element)
    findings = []
    for piece, piece_links in zip(pieces, links, strict=True):
        nodes = tuple(sorted(piece))
        names = tuple(e.name for e in piece_links)
        listed = ", ".join(nodes)
        if piece_links and all(_is_current_source(e) for e in piece_links):
            findings.append(
                Finding(
                    "current-source-cutset",
                    f"nodes {listed} connect to the rest only through current sources "
                    f"{', '.join(names)}: their voltages are undetermined",
                    names,
                    nodes,
                )
            )
        else:
            through = f"only through {', '.join(names)}" if names else "through no element"
            findings.append(
                Finding(
                    "no-dc-path",
                    f"nodes {listed} have no DC path to ground (connected {through})",
                    names,
                    nodes,
                )
            )
    return findings


def _voltage_loops(elements: list[Element]) -> list[Finding]:
    """Loops of V, E/H outputs and inductors, found as the edge that closes each one."""
    forest = nx.Graph()
    joined = nx.utils.UnionFind()  # near-constant-time "already connected?" before any path
    findings = []
    for element in elements:
        if not _fixes_voltage(element):
            continue
        a, b = _output_nodes(element)
        if a == b:
            loop, nodes = (element.name,), (a,)
        elif joined[a] == joined[b]:
            path = nx.shortest_path(forest, a, b)
            loop = tuple(forest.edges[u, v]["name"] for u, v in zip(path, path[1:], strict=False))
            loop += (element.name,)
            nodes = tuple(path)
        else:
            forest.add_edge(a, b, name=element.name)
            joined.union(a, b)
            continue
        findings.append(
            Finding(
                "voltage-loop",
                f"{', '.join(loop)} form a loop of voltage sources and inductors "
                f"through nodes {', '.join(nodes)}",
                loop,
                nodes,
            )
        )
    return findings


__all__ = ["Finding", "check_circuit", "electrical_findings"]
