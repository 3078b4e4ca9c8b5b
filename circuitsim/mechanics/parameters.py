"""Model parameters: numbers, or expressions of other parameters (``k = "2*ky + W*lambda/b"``).

A parameter written as a string is an expression of other parameters, in any order in the
file; they are evaluated in dependency order, so a cycle (``a = "b"``, ``b = "2*a"``) or a name
that is no parameter is refused when the file is read. A value given for a parameter at run
time (``--param W=22000``) replaces its expression, and every parameter computed from it
follows: the defaults of the file are what the expressions give at the other defaults.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import SimpleNamespace

from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.expressions import ExpressionError, Item


@dataclass(frozen=True)
class Parameter:
    """A named model parameter.

    Attributes
    ----------
    name : str
    value : float
        Default value in ``unit`` (for an expression: its value at the other defaults).
    unit, description : str
    expression : Item or None
        The expression the file gives for it; None for a plain number.
    """

    name: str
    value: float
    unit: str = ""
    description: str = ""
    expression: Item | None = None


def read_parameters(reader, table: dict, check_identifier) -> dict[str, Parameter]:
    """The ``[parameters]`` table, checked and evaluated at its defaults, in file order.

    Parameters
    ----------
    reader : modelfile reader
        Supplies ``fail``, ``check_keys``, ``string`` and ``expression`` (one file's errors).
    table : dict
        The TOML table.
    check_identifier : callable
        ``check_identifier(reader, name, key)`` refuses invalid or reserved names.

    Raises
    ------
    ModelError
        Wrong type, bad expression, unknown name, a cycle, or a value that cannot be
        evaluated (division by zero ...), naming the parameter's key.
    """
    raw: dict[str, tuple[str, float | None, Item | None, str, str]] = {}
    for name, value in table.items():
        key = f"parameters.{name}"
        check_identifier(reader, name, key)
        unit, description = "", ""
        if isinstance(value, dict):
            reader.check_keys(value, key, ("value", "unit", "description"))
            unit = reader.string(value, "unit", key, default="")
            description = reader.string(value, "description", key, default="")
            if "value" not in value:
                raise reader.fail(f"{key}.value", "missing key")
            value = value["value"]
            key = f"{key}.value"
        if isinstance(value, str):
            raw[name] = (key, None, reader.expression(value, key), unit, description)
            continue
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise reader.fail(
                key, f"wrong type: expected a number or an expression, got {_type(value)}"
            )
        try:
            number = float(value)
        except OverflowError:
            number = math.inf
        if not math.isfinite(number):
            raise reader.fail(key, f"must be a finite number, got {value!r}")
        raw[name] = (key, number, None, unit, description)
    order = _dependency_order(reader, {n: r[2] for n, r in raw.items()})
    values: dict[str, float] = {}
    for name in order:
        key, number, item, _, _ = raw[name]
        values[name] = number if item is None else _evaluate(reader.fail, item, values)
    return {
        name: Parameter(name, values[name], unit, description, item)
        for name, (_, _, item, unit, description) in raw.items()
    }


def _dependency_order(reader, expressions: dict[str, Item | None]) -> list[str]:
    """Parameter names so that each comes after those its expression reads."""
    known = ", ".join(expressions) or "none"
    for item in expressions.values():
        for used in sorted(item.expression.names) if item else ():
            if used not in expressions:
                raise reader.fail(
                    item.key, f"unknown name {used!r} in {item.expression.text!r} "
                    f"(a parameter may use other parameters: {known})"
                )  # fmt: skip
    # Kahn's algorithm (no recursion: a chain of any length is fine)
    uses = {n: set(i.expression.names) if i else set() for n, i in expressions.items()}
    used_by: dict[str, list[str]] = {n: [] for n in expressions}
    for name, names in uses.items():
        for used in names:
            used_by[used].append(name)
    waiting = {name: len(names) for name, names in uses.items()}
    ready = [name for name in expressions if not waiting[name]]
    order: list[str] = []
    while ready:
        name = ready.pop()
        order.append(name)
        for user in used_by[name]:
            waiting[user] -= 1
            if not waiting[user]:
                ready.append(user)
    if len(order) == len(expressions):
        return order
    # every parameter left waits on another one left: follow them until a name repeats
    left = [name for name in expressions if waiting[name]]
    path, name = [], left[0]
    while name not in path:
        path.append(name)
        name = next(used for used in sorted(uses[name]) if waiting[used])
    cycle = path[path.index(name) :] + [name]
    item = expressions[cycle[0]]
    raise reader.fail(item.key, f"cycle in parameter expressions: {' -> '.join(cycle)}")


def _evaluate(fail, item: Item, env: Mapping[str, float]) -> float:
    try:
        return item.expression(dict(env))
    except ExpressionError as exc:
        raise fail(item.key, f"bad expression: {exc}") from None


def evaluate_parameters(
    parameters: Mapping[str, Parameter], given: Mapping[str, float], file: str
) -> dict[str, float]:
    """Every parameter's value, with ``given`` values replacing defaults or expressions.

    Parameters
    ----------
    parameters : dict of str to Parameter
        As read from the file (file order).
    given : dict of str to float
        Values set for this run (already checked to be known, finite numbers).
    file : str
        The model file, for errors.

    Returns
    -------
    dict of str to float
        In file order.

    Raises
    ------
    ModelError
        An expression that cannot be evaluated at these values (``1 / (V - 55)`` at V = 55),
        naming the parameter's key and the values given.
    """
    def fail(key: str | None, message: str) -> ModelError:
        shown = ", ".join(f"{k}={v:g}" for k, v in given.items())
        return ModelError(f"{message} (with {shown})" if shown else message, file, key)

    values = {name: float(given.get(name, p.value)) for name, p in parameters.items()}
    computed = {n: p.expression for n, p in parameters.items() if p.expression and n not in given}
    if not computed:
        return values
    reader = SimpleNamespace(fail=fail)
    for name in _dependency_order(reader, {n: computed.get(n) for n in parameters}):
        if name in computed:
            values[name] = _evaluate(fail, computed[name], values)
    return values


def _type(value) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean"}.get(
        type(value), type(value).__name__
    )
