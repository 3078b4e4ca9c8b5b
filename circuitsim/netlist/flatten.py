"""Expand subcircuit instances and evaluate every expression: a flat, all-float Circuit.

Rules (ngspice's, where ngspice has one):

- Parameters: global ``.param`` values are evaluated in written order (a later one may use an
  earlier one). An instance's parameters are evaluated in the caller's scope; the subcircuit's
  defaults are then evaluated in order, each one replaced by the instance's value when given,
  so later defaults see the overrides (``params: a=1 b={2*a}`` with ``a=5`` gives ``b=10``).
  Inside a body the names visible are those of the scope where the ``.subckt`` was defined
  (global params for a top-level definition, the enclosing instance's for a nested one),
  shadowed by the subcircuit's own.
- Names: an element ``R1`` inside instance ``XU1`` (inside ``X2``) becomes ``R.X2.XU1.R1`` -
  ngspice's form, type letter first, so :attr:`Element.letter` still tells the kind.
  Top-level elements keep their names.
- Nodes: ports map to the instance's connection nodes; ground ``0`` stays global; any other
  internal node ``n1`` becomes ``x2.xu1.n1`` (lower case, instance path then node).
- Models: a ``.model`` inside a ``.subckt`` is local to it (and to subcircuits defined inside
  it). Each instance gets its own copy under the name ``<instance path>.<model>``
  (``x2.xu1.dmod``, lower case) with its parameters evaluated in the instance's scope;
  ``Diode.model``, ``Jfet.model``, ``Bjt.model`` and ``Switch.model`` are rewritten to it.
  Global models keep their names.
  A model that no scope defines is left as written, for the topology checks to report.
- F/H controls (also each of a POLY's) naming a voltage source of the same body are renamed
  with it; other names are left alone (they refer to the top level).
- Subcircuit lookup is lexical too: a body sees its own nested definitions, then those of the
  scopes around its definition.

Errors are :class:`~circuitsim.netlist.errors.NetlistError` (file = ``circuit.source``, no
line: a Circuit does not remember lines) naming the instance path and element: unknown
subcircuit, wrong number of connections, recursion (direct or indirect), an instance parameter
the subcircuit does not declare, an undefined parameter, a bad expression, and circuits that
would expand past 200 000 elements and instances or 64 levels.

Given a ``problems`` list, :func:`flatten` goes on past values that do not evaluate: each one
is recorded there as a :class:`ValueProblem` and stands as NaN in the result, and a value
that fails only because it uses such a NaN parameter is not recorded again. The topology
checks use this to report every bad value at once; the structural errors above still raise.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from circuitsim.netlist.circuit import (
    Circuit,
    Element,
    Expression,
    Model,
    Pulse,
    Pwl,
    Sin,
    Subcircuit,
    SubcircuitCall,
    Value,
)
from circuitsim.netlist.errors import NetlistError
from circuitsim.netlist.expressions import evaluate, names_in
from circuitsim.netlist.names import fold

__all__ = ["flatten", "evaluate_value", "ValueProblem", "MAX_ELEMENTS", "MAX_DEPTH"]

MAX_ELEMENTS = 200_000
MAX_DEPTH = 64

_NODE_FIELDS = (
    "positive",
    "negative",
    "control_positive",
    "control_negative",
    "anode",
    "cathode",
    "drain",
    "gate",
    "source",
    "collector",
    "base",
    "emitter",
)


@dataclass(frozen=True)
class ValueProblem:
    """A value that could not be evaluated, recorded by :func:`flatten` when asked to go on.

    Attributes
    ----------
    what : str
        The value: instance path, then element or parameter and field (``"R1 resistance"``,
        ``"global parameter p"``, ``"in X1: R.X1.RB resistance"``).
    message : str
        Why it failed, from the expression evaluator (``"division by zero in '1/0'"``).
    element : str or None
        Flat name of the element holding the value; None for parameters, models, ``.ic`` and
        options.
    undefined : str or None
        The parameter name, when the cause is an undefined parameter.
    """

    what: str
    message: str
    element: str | None = None
    undefined: str | None = None

    def __str__(self) -> str:
        return f"{self.what}: {self.message}"


@dataclass
class _Scope:
    params: dict[str, float]
    models: dict[str, str]  # visible model name (lower) -> flat model key
    subcircuits: dict[str, tuple[Subcircuit, _Scope]]  # name -> (definition, defining scope)


class _Flattener:
    def __init__(self, circuit: Circuit, problems: list[ValueProblem] | None = None):
        self.circuit = circuit
        self.file = circuit.source
        self.elements: list[Element] = []
        self.models: dict[str, Model] = {}
        self.expanded = 0  # elements and instances so far
        self.problems = problems
        self.owner: str | None = None  # flat name of the element being evaluated

    def error(self, message: str) -> NetlistError:
        return NetlistError(message, file=self.file)

    def value(self, value: object, params: Mapping[str, float], what: str) -> float:
        try:
            return evaluate_value(value, params)
        except ValueError as exc:
            why = str(exc)
            included = getattr(value, "included", None)
            if included is not None:  # name the file, never quote it
                why = f"an expression of the included file {included} cannot be evaluated"
            if self.problems is None:
                raise self.error(f"{what}: {why}") from None
            if not _uses_failed(value, params):
                undefined = None if included else getattr(exc, "name", None)
                self.problems.append(ValueProblem(what, why, self.owner, undefined))
            return math.nan

    # --- scopes ---
    def scope_for(
        self,
        defining: _Scope | None,
        own_params: Mapping[str, Value],
        overrides: Mapping[str, float],
        models: Mapping[str, Model],
        subcircuits: Mapping[str, Subcircuit],
        path: str,
        where: str,
    ) -> _Scope:
        params = dict(defining.params) if defining else {}
        for name, default in own_params.items():
            key = fold(name)
            if key in overrides:
                params[key] = overrides[key]
            else:
                params[key] = self.value(default, params, f"{where}parameter {name}")
        visible_models = dict(defining.models) if defining else {}
        for name, model in models.items():
            flat_key = f"{path}.{fold(name)}" if path else fold(name)
            if flat_key in self.models:
                raise self.error(f"{where}model {name!r} defined twice")
            self.models[flat_key] = Model(
                flat_key if path else model.name,
                model.kind,
                {
                    k: self.value(v, params, f"{where}model {model.name} parameter {k}")
                    for k, v in model.params.items()
                },
            )
            visible_models[fold(name)] = flat_key
        scope = _Scope(params, visible_models, dict(defining.subcircuits) if defining else {})
        for name, sub in subcircuits.items():
            scope.subcircuits[fold(name)] = (sub, scope)
        return scope

    # --- expansion ---
    def expand(
        self,
        elements: list[Element],
        scope: _Scope,
        path: list[str],
        nodes: Mapping[str, str],
        stack: list[Subcircuit],
    ) -> None:
        prefix = ".".join(path)
        node_prefix = fold(prefix)
        where = f"in {prefix}: " if path else ""

        def node(name: str) -> str:
            key = fold(name)
            if key == "0":
                return "0"
            if key in nodes:
                return nodes[key]
            return f"{node_prefix}.{key}" if path else key

        def element_name(name: str) -> str:
            return f"{name[:1].upper()}.{prefix}.{name}" if path else name

        local = {fold(e.name): element_name(e.name) for e in elements}
        for element in elements:
            if isinstance(element, SubcircuitCall):
                self.call(element, scope, path, node, stack, where)
                continue
            self.count(where)
            self.elements.append(
                self.flat_element(element, scope, element_name, node, local, where)
            )

    def count(self, where: str) -> None:
        """Count one element or instance; a cap keeps fan-out trees (2**60 calls) finite."""
        self.expanded += 1
        if self.expanded > MAX_ELEMENTS:
            raise self.error(
                f"{where}the flat circuit would exceed {MAX_ELEMENTS} elements and instances"
            )

    def call(
        self,
        call: SubcircuitCall,
        scope: _Scope,
        path: list[str],
        node: Callable[[str], str],
        stack: list[Subcircuit],
        where: str,
    ) -> None:
        self.count(where)
        key = fold(call.subcircuit)
        found = scope.subcircuits.get(key)
        if found is None:
            raise self.error(f"{where}{call.name}: unknown subcircuit {call.subcircuit!r}")
        sub, defining = found
        if any(s is sub for s in stack):
            chain = " -> ".join([*(s.name for s in stack), sub.name])
            raise self.error(f"{where}{call.name}: recursive subcircuit {chain}")
        if len(stack) >= MAX_DEPTH:
            raise self.error(f"{where}{call.name}: subcircuits nested deeper than {MAX_DEPTH}")
        if len(call.connections) != len(sub.ports):
            raise self.error(
                f"{where}{call.name}: subcircuit {sub.name} has {len(sub.ports)} port(s) "
                f"({' '.join(sub.ports)}), got {len(call.connections)} connection(s)"
            )
        declared = {fold(k) for k in sub.params}
        overrides: dict[str, float] = {}
        self.owner = f"X.{'.'.join(path)}.{call.name}" if path else call.name
        for name, value in call.params.items():
            if fold(name) not in declared:
                known = ", ".join(sorted(declared)) or "none"
                raise self.error(
                    f"{where}{call.name}: subcircuit {sub.name} has no parameter {name!r} "
                    f"(its parameters: {known})"
                )
            overrides[fold(name)] = self.value(
                value, scope.params, f"{where}{call.name} parameter {name}"
            )
        self.owner = None
        inner_path = [*path, call.name]
        inner_where = f"in {'.'.join(inner_path)}: "
        inner = self.scope_for(
            defining,
            sub.params,
            overrides,
            sub.models,
            sub.subcircuits,
            fold(".".join(inner_path)),
            inner_where,
        )
        mapping = {
            fold(port): node(conn) for port, conn in zip(sub.ports, call.connections, strict=True)
        }
        self.expand(sub.elements, inner, inner_path, mapping, [*stack, sub])

    def flat_element(
        self,
        element: Element,
        scope: _Scope,
        element_name: Callable[[str], str],
        node: Callable[[str], str],
        local: Mapping[str, str],
        where: str,
    ) -> Element:
        what = f"{where}{element.name}"
        self.owner = element_name(element.name)
        kwargs: dict[str, object] = {}
        for f in dataclasses.fields(element):
            value = getattr(element, f.name)
            if f.name == "name":
                kwargs[f.name] = element_name(value)
            elif f.name in _NODE_FIELDS:
                kwargs[f.name] = node(value)
            elif f.name == "model":
                kwargs[f.name] = scope.models.get(fold(value), fold(value))
            elif f.name == "control":
                kwargs[f.name] = local.get(fold(value), value)
            elif f.name == "substrate":
                kwargs[f.name] = None if value is None else node(value)
            elif f.name == "controls":  # POLY: node pairs (E, G) or source names (F, H)
                kwargs[f.name] = tuple(
                    (node(c[0]), node(c[1])) if isinstance(c, tuple) else local.get(fold(c), c)
                    for c in value
                )
            elif f.name == "coefficients":
                kwargs[f.name] = tuple(
                    self.value(c, scope.params, f"{what} coefficient {k}")
                    for k, c in enumerate(value)
                )
            elif f.name == "initial":
                kwargs[f.name] = value
            else:
                kwargs[f.name] = self.field_value(value, scope.params, f"{what} {f.name}")
        self.owner = None
        return type(element)(**kwargs)

    def field_value(self, value: object, params: Mapping[str, float], what: str) -> object:
        if value is None:
            return None
        if isinstance(value, Sin | Pulse):
            return type(value)(
                **{
                    f.name: self.field_value(getattr(value, f.name), params, f"{what} {f.name}")
                    for f in dataclasses.fields(value)
                }
            )
        if isinstance(value, Pwl):
            return Pwl(
                tuple(
                    (
                        self.value(t, params, f"{what} time {i + 1}"),
                        self.value(v, params, f"{what} value {i + 1}"),
                    )
                    for i, (t, v) in enumerate(value.points)
                )
            )
        return self.value(value, params, what)


def _uses_failed(value: object, params: Mapping[str, float]) -> bool:
    """Whether ``value`` is an expression naming a parameter that already failed (NaN)."""
    if not isinstance(value, Expression):
        return False
    try:
        names = names_in(value.text)
    except ValueError:
        return False
    lowered = {fold(str(k)): v for k, v in params.items()}
    return any(math.isnan(lowered.get(name, 0.0)) for name in names)


def evaluate_value(value: object, params: Mapping[str, float]) -> float:
    """A Value as a float: numbers pass through, Expressions are evaluated against ``params``.

    Raises ValueError for anything else or a failed evaluation.
    """
    if isinstance(value, bool):
        raise ValueError(f"expected a number, got {value!r}")
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, Expression):
        return evaluate(value.text, params)
    raise ValueError(f"expected a number or Expression, got {value!r}")


def flatten(circuit: Circuit, problems: list[ValueProblem] | None = None) -> Circuit:
    """A new Circuit with every subcircuit instance expanded and every value a float.

    Parameters
    ----------
    circuit : Circuit
        A circuit as read or built; it is not modified.
    problems : list of ValueProblem, optional
        When given, values that do not evaluate are appended to it (and are NaN in the
        result) instead of raising; see the module docstring.

    Returns
    -------
    Circuit
        No :class:`SubcircuitCall`, no subcircuits, no Expression; ``params`` holds the
        evaluated global parameters, ``models`` the global models plus one copy of each local
        model per instance.

    Raises
    ------
    NetlistError
        See the module docstring; with ``problems`` given, only for the structural errors.
    """
    work = _Flattener(circuit, problems)
    top = work.scope_for(
        None, circuit.params, {}, circuit.models, circuit.subcircuits, "", "global "
    )
    work.expand(circuit.elements, top, [], {}, [])
    for analysis in circuit.analyses:
        for f in dataclasses.fields(analysis):
            value = getattr(analysis, f.name)
            if isinstance(value, Expression):  # analyses hold floats; be safe for builders
                raise work.error(f"analysis {analysis!r} holds an unevaluated expression")
    initial = {
        node: work.value(value, top.params, f".ic v({node})")
        for node, value in circuit.initial_conditions.items()
    }
    options: dict[str, object] = {}
    for name, value in circuit.options.items():
        if isinstance(value, Expression):
            value = work.value(value, top.params, f"option {name}")
        options[name] = value
    return Circuit(
        title=circuit.title,
        elements=work.elements,
        models=work.models,
        subcircuits={},
        params=dict(top.params),
        analyses=list(circuit.analyses),
        initial_conditions=initial,
        options=options,  # type: ignore[arg-type]
        control=list(circuit.control),
        source=circuit.source,
    )
