"""Reading a model file (TOML) into a :class:`~circuitsim.mechanics.model.Model`.

Everything the file says is checked here, and every problem becomes a ModelError naming the
file, the dotted key and what is wrong. The format is documented in docs/model.md. Finding
the file, reading its TOML and the checked walk through its tables (TableReader):
:mod:`circuitsim.mechanics.tomlfile`; here, what each section means.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.expressions import Item
from circuitsim.mechanics.forcingfile import ForcingSpec, read_forcing
from circuitsim.mechanics.parameters import Parameter, read_parameters
from circuitsim.mechanics.shapes import SHAPES, ShapeSpec, read_shape
from circuitsim.mechanics.tomlfile import (  # noqa: F401 - BUILTIN, MAX_FILE_BYTES ... re-exported
    BUILTIN,
    MAX_FILE_BYTES,
    TableReader,
    builtin_path,
    check_identifier,
    load_toml,
    model_path,
    read_float,
    shipped_models,
    type_name,
)

KINDS = ("second_order", "first_order")
TOP_KEYS = {
    "model": "name, kind, description",
    "coordinates": "second-order coordinate names and units",
    "states": "first-order state names and units",
    "parameters": "named parameters with defaults",
    "options": "command-line option -> parameter",
    "coefficients": "named coefficient sets",
    "matrices": "M, C, K (second order) or A (first order)",
    "elements": "masses, springs, dampers, creep, contacts (second order; assembled into M, C, K)",
    "nonlinear": "piecewise-linear terms: abs() form, deadzone, saturation, table, fit",
    "forcing": "inputs: sinusoids, time series, steps, bumps",
    "initial": "initial conditions",
    "circuit": "free-form hints for the circuit translator",
}


@dataclass(frozen=True)
class AbsSpec:
    """``gain * |row . x + offset|`` before evaluation; row maps state index -> Item."""

    gain: Item
    row: dict[int, Item]
    offset: Item


@dataclass(frozen=True)
class NonlinearSpec:
    """A switchable piecewise-linear group as written in ``[nonlinear.<name>]``."""

    name: str
    key: str
    description: str
    enabled: bool
    enters: dict[int, Item]
    linear: dict[int, Item]
    constant: Item
    abs_terms: tuple[AbsSpec, ...]
    t_on: Item | None
    shapes: tuple[ShapeSpec, ...] = ()


@dataclass(frozen=True)
class ModelSpec:
    """The checked, still symbolic content of a model file."""

    file: str
    name: str
    description: str
    kind: str
    coordinates: tuple[str, ...]
    coordinate_units: tuple[str, ...]
    states: tuple[str, ...]
    units: tuple[str, ...]
    parameters: dict[str, Parameter]
    options: dict[str, str]
    coefficient_sets: dict[str, tuple[tuple[str, Item], ...]]
    default_coefficients: str
    matrices: dict[str, list[list[Item]] | list[Item]]
    nonlinear: dict[str, NonlinearSpec]
    forcing: dict[str, ForcingSpec]
    initial: dict[int, Item]
    circuit: dict
    time_unit: str = "s"


def read_model(path: str | Path | None = None) -> ModelSpec:
    """Read and check a model file; ``None`` reads the built-in wheelset, a name without a
    file of that name a shipped model (``"bogie"``, see :func:`model_path`).

    Raises
    ------
    ModelError
        Naming the file, the dotted key and what is wrong.
    """
    if path is not None and "\x00" in str(path):
        raise ModelError("cannot read: the path contains a NUL character", file=repr(str(path)))
    try:
        path = model_path(path)
    except (OSError, ValueError) as exc:  # a name too long for the file system
        reason = getattr(exc, "strerror", None) or str(exc)
        raise ModelError(f"cannot read: {reason}", file=str(path)) from None
    file = str(path)
    reader = TableReader(file)
    document = load_toml(path, reader)
    reader.check_keys(document, "", tuple(TOP_KEYS))

    model = reader.table(document.get("model"), "model")
    reader.check_keys(model, "model", ("name", "description", "kind", "time_unit"))
    name = reader.string(model, "name", "model")
    description = reader.string(model, "description", "model", default="")
    # "s" by default; "" or "1" for a dimensionless time (rates are then per unit time)
    time_unit = reader.string(model, "time_unit", "model", default="s").strip()
    time_unit = "" if time_unit == "1" else time_unit
    kind = reader.string(model, "kind", "model")
    if kind not in KINDS:
        raise reader.fail("model.kind", f"must be one of {', '.join(KINDS)}, got {kind!r}")

    if kind == "second_order":
        if "states" in document:
            raise reader.fail("states", "a second_order model names [coordinates], not [states]")
        section = reader.table(document.get("coordinates"), "coordinates")
        reader.check_keys(section, "coordinates", ("names", "units"))
        coordinates = reader.names(section, "names", "coordinates")
        coordinate_units = _units(reader, section, "coordinates", len(coordinates))
        states = coordinates + tuple(f"{q}_dot" for q in coordinates)
        units = coordinate_units + tuple(_rate(u, time_unit) for u in coordinate_units)
        equations = coordinates
    else:
        if "coordinates" in document:
            raise reader.fail(
                "coordinates", "a first_order model names [states], not [coordinates]"
            )
        section = reader.table(document.get("states"), "states")
        reader.check_keys(section, "states", ("names", "units"))
        states = reader.names(section, "names", "states")
        units = _units(reader, section, "states", len(states))
        coordinates, coordinate_units = (), ()
        equations = states

    parameters = _parameters(reader, document)
    options = _options(reader, document, parameters, states)
    sets, default_set = _coefficient_sets(reader, document, parameters)
    from_elements = "elements" in document
    matrices = _matrices(reader, document, kind, len(equations), required=not from_elements)
    nonlinear = {
        group: _nonlinear(reader, table, f"nonlinear.{group}", states, equations, kind)
        for group, table in reader.table(document.get("nonlinear"), "nonlinear", False).items()
    }
    if from_elements:
        if kind != "second_order":
            raise reader.fail("elements", "only a second_order model is built from elements")
        from circuitsim.mechanics.elements import read_elements  # it builds on this module

        matrices, nonlinear = read_elements(
            reader, document, coordinates, parameters, sets, matrices, nonlinear
        )
    forcing = {
        group: _forcing(reader, table, f"forcing.{group}", equations)
        for group, table in reader.table(document.get("forcing"), "forcing", False).items()
    }
    initial_table = reader.table(document.get("initial"), "initial", False)
    initial = _row(reader, initial_table, "initial", states, kind, allow_coordinates=False)
    circuit = reader.table(document.get("circuit"), "circuit", False)
    _circuit_hints(reader, circuit, states, parameters, tuple(nonlinear), tuple(forcing))
    return ModelSpec(
        file=file,
        name=name,
        description=description,
        kind=kind,
        coordinates=coordinates,
        coordinate_units=coordinate_units,
        states=states,
        units=units,
        parameters=parameters,
        options=options,
        coefficient_sets=sets,
        default_coefficients=default_set,
        matrices=matrices,
        nonlinear=nonlinear,
        forcing=forcing,
        initial=initial,
        circuit=dict(circuit),
        time_unit=time_unit,
    )


def _rate(unit: str, time_unit: str = "s") -> str:
    """The unit of a coordinate's rate: ``m/s``; with a dimensionless time, the unit itself."""
    if not time_unit:
        return unit or "1"
    return f"1/{time_unit}" if unit in ("", "1") else f"{unit}/{time_unit}"


def _units(reader: TableReader, section: dict, key: str, count: int) -> tuple[str, ...]:
    if "units" not in section:
        return ("",) * count
    value = section["units"]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise reader.fail(f"{key}.units", "wrong type: expected a list of strings")
    if len(value) != count:
        raise reader.fail(f"{key}.units", f"wrong length: {len(value)} units for {count} names")
    return tuple(value)


def _circuit_hints(
    reader: TableReader,
    circuit: dict,
    states: tuple[str, ...],
    parameters: dict,
    terms: tuple[str, ...],
    forcings: tuple[str, ...],
) -> None:
    """Check ``[circuit]``, the translator's hints (docs/translator.md, synthesis/naming.py).

    Part names are keyed by what they belong to (a state, a piecewise-linear term, a forcing
    term): a key naming nothing of the model, or a name that is not a string, would otherwise
    be dropped or turned into a part name without a word. Other keys are the author's own
    (notes ...) and pass unchanged. ``t_stop`` (model seconds simulated) becomes the
    netlist's ``.tran`` stop time and ``ode``'s end time, ``time_scale`` (K: one model second
    takes 1/K circuit seconds) the translator's default time scale: both checked here so that
    a bad one is reported against the model file, not as an unreadable netlist line.
    """
    by_state = {"integrators", "inverters", "capacitors"}
    owners = {"switches": ("nonlinear term", terms), "sources": ("forcing term", forcings)}
    owners.update({key: ("state", states) for key in by_state})
    inputs = states + terms + forcings + ("constant",)
    for key, (what, known) in owners.items():
        _part_names(reader, circuit.get(key), f"circuit.{key}", what, known)
    resistors = reader.table(circuit.get("resistors"), "circuit.resistors", False)
    for state, table in resistors.items():
        where = f"circuit.resistors.{state}"
        if state not in states:
            raise reader.fail(where, f"not a state of the model (states: {', '.join(states)})")
        _part_names(reader, table, where, "state, term or forcing", inputs)
    if "speed" in circuit:
        speed = reader.table(circuit["speed"], "circuit.speed")
        reader.check_keys(speed, "circuit.speed", ("parameter", "entries"))
        name = reader.string(speed, "parameter", "circuit.speed")
        if name not in parameters:
            raise reader.fail(
                "circuit.speed.parameter", f"unknown parameter {name!r} (known: "
                f"{', '.join(parameters)})"
            )  # fmt: skip
        entries = speed.get("entries", [])
        if not isinstance(entries, list) or not all(
            isinstance(e, list) and len(e) == 2 and all(x in states for x in e) for e in entries
        ):
            raise reader.fail(
                "circuit.speed.entries", "expected a list of [state, state] pairs of the model"
            )
    for name, what in (("t_stop", "a number of seconds"), ("time_scale", "a number")):
        if name in circuit:
            value = read_float(reader, circuit[name], f"circuit.{name}", what)
            if not (math.isfinite(value) and value > 0):
                raise reader.fail(
                    f"circuit.{name}", f"must be a positive {what[2:]}, got {circuit[name]}"
                )


def _part_names(reader: TableReader, value, key: str, what: str, known: tuple[str, ...]) -> None:
    """A table of part names (strings) keyed by names in ``known`` (each a ``what``)."""
    for name, part in reader.table(value, key, False).items():
        if name not in known:
            raise reader.fail(
                f"{key}.{name}", f"not a {what} of the model (known: {', '.join(known)})"
            )
        if not isinstance(part, str) or not part.strip():
            raise reader.fail(f"{key}.{name}", f"expected a part name, got {type_name(part)}")


def _parameters(reader: TableReader, document: dict) -> dict[str, Parameter]:
    table = reader.table(document.get("parameters"), "parameters", False)
    return read_parameters(reader, table, check_identifier)


def _options(
    reader: TableReader, document: dict, parameters: dict, states: tuple[str, ...]
) -> dict[str, str]:
    """Option -> parameter; ``state`` names a state instead (the one the verbs push and
    measure by default: STATE_OPTION)."""
    table = reader.table(document.get("options"), "options", False)
    options = {}
    for option, target in table.items():
        key = f"options.{option}"
        what = "a state" if option == STATE_OPTION else "a parameter"
        if not isinstance(target, str):
            raise reader.fail(key, f"wrong type: expected {what} name, got {type_name(target)}")
        if option == STATE_OPTION:
            if target not in states:
                raise reader.fail(key, f"unknown state {target!r} (states: {', '.join(states)})")
        elif target not in parameters:
            raise reader.fail(key, f"unknown parameter {target!r}")
        options[option] = target
    return options


#: The ``[options]`` key that names a state (``state = "y2"``): the state ``hunting``,
#: ``sweep``, ``tolerance``, the plots and ``--y0`` use when no ``--state`` is given.
STATE_OPTION = "state"


def _coefficient_sets(reader: TableReader, document: dict, parameters: dict):
    table = reader.table(document.get("coefficients"), "coefficients", False)
    sets: dict[str, tuple[tuple[str, Item], ...]] = {}
    default = None
    for name, entries in table.items():
        key = f"coefficients.{name}"
        if name == "default":
            if not isinstance(entries, str):
                raise reader.fail(key, f"wrong type: expected a set name, got {type_name(entries)}")
            default = entries
            continue
        entries = reader.table(entries, key)
        items = []
        for coefficient, value in entries.items():
            check_identifier(reader, coefficient, f"{key}.{coefficient}")
            if coefficient in parameters:
                raise reader.fail(
                    f"{key}.{coefficient}", "a coefficient may not reuse a parameter's name"
                )
            items.append((coefficient, reader.expression(value, f"{key}.{coefficient}")))
        sets[name] = tuple(items)
    if not sets:
        sets = {"default": ()}
    if default is None:
        default = next(iter(sets))
    elif default not in sets:
        raise reader.fail(
            "coefficients.default", f"unknown set {default!r} (sets: {', '.join(sets)})"
        )
    return sets, default


def _matrices(reader: TableReader, document: dict, kind: str, size: int, required=True) -> dict:
    """``[matrices]``; not ``required`` (a model from ``[elements]``): optional, M, K too."""
    table = reader.table(document.get("matrices"), "matrices", required)
    if kind == "second_order":
        square, vectors, needed = ("M", "C", "K"), ("F",), ("M", "K")
    else:
        square, vectors, needed = ("A",), ("b",), ("A",)
    reader.check_keys(table, "matrices", square + vectors)
    for name in needed if required else ():
        if name not in table:
            raise reader.fail(f"matrices.{name}", "missing key")
    matrices: dict = {}
    for name in square:
        if name not in table:
            continue
        key = f"matrices.{name}"
        rows = table[name]
        if not isinstance(rows, list) or not all(isinstance(r, list) for r in rows):
            raise reader.fail(key, "wrong type: expected an array of rows (arrays)")
        if len(rows) != size:
            raise reader.fail(key, f"wrong number of rows: expected {size}, got {len(rows)}")
        matrices[name] = []
        for i, row in enumerate(rows):
            if len(row) != size:
                raise reader.fail(
                    f"{key}[{i}]", f"wrong row length: expected {size}, got {len(row)}"
                )
            matrices[name].append(
                [reader.expression(v, f"{key}[{i}][{j}]") for j, v in enumerate(row)]
            )
    for name in vectors:
        if name not in table:
            continue
        key = f"matrices.{name}"
        values = table[name]
        if not isinstance(values, list):
            raise reader.fail(key, f"wrong type: expected an array, got {type_name(values)}")
        if len(values) != size:
            raise reader.fail(key, f"wrong length: expected {size}, got {len(values)}")
        matrices[name] = [reader.expression(v, f"{key}[{j}]") for j, v in enumerate(values)]
    return matrices


def _row(
    reader: TableReader,
    value,
    key: str,
    names: tuple[str, ...],
    kind: str,
    allow_coordinates: bool = True,
) -> dict[int, Item]:
    """A vector over ``names`` written as a table {name = expr} or an array; index -> Item.

    For rows over the states of a second-order model an array may also list the coordinates
    only (the rates get weight 0).
    """
    if isinstance(value, dict):
        row = {}
        for name, entry in value.items():
            if name not in names:
                raise reader.fail(f"{key}.{name}", f"unknown name (known: {', '.join(names)})")
            row[names.index(name)] = reader.expression(entry, f"{key}.{name}")
        return row
    if isinstance(value, list):
        lengths = [len(names)]
        if kind == "second_order" and allow_coordinates and len(names) % 2 == 0:
            lengths.append(len(names) // 2)
        if len(value) not in lengths:
            expected = " or ".join(str(n) for n in lengths)
            raise reader.fail(
                key,
                f"wrong row length: expected {expected} ({', '.join(names)}), got {len(value)}",
            )
        return {i: reader.expression(v, f"{key}[{i}]") for i, v in enumerate(value)}
    raise reader.fail(key, f"wrong type: expected a table or an array, got {type_name(value)}")


def _optional(reader: TableReader, table: dict, name: str, key: str, default) -> Item:
    return reader.expression(table.get(name, default), f"{key}.{name}")


def _nonlinear(reader, table, key, states, equations, kind) -> NonlinearSpec:
    table = reader.table(table, key)
    allowed = ("description", "enabled", "enters", "linear", "constant", "abs", "t_on")
    reader.check_keys(table, key, allowed + tuple(SHAPES))
    if "enters" not in table:
        raise reader.fail(f"{key}.enters", "missing key")
    enters = _row(reader, table["enters"], f"{key}.enters", equations, "first_order")
    linear = _row(reader, table.get("linear", {}), f"{key}.linear", states, kind)
    abs_list = table.get("abs", [])
    if not isinstance(abs_list, list):
        raise reader.fail(
            f"{key}.abs", f"wrong type: expected an array of tables, got {type_name(abs_list)}"
        )
    terms = []
    for i, entry in enumerate(abs_list):
        sub = f"{key}.abs[{i}]"
        entry = reader.table(entry, sub)
        reader.check_keys(entry, sub, ("gain", "row", "offset"))
        for needed in ("gain", "row"):
            if needed not in entry:
                raise reader.fail(f"{sub}.{needed}", "missing key")
        terms.append(
            AbsSpec(
                gain=reader.expression(entry["gain"], f"{sub}.gain"),
                row=_row(reader, entry["row"], f"{sub}.row", states, kind),
                offset=_optional(reader, entry, "offset", sub, 0.0),
            )
        )
    t_on = None if "t_on" not in table else reader.expression(table["t_on"], f"{key}.t_on")

    def read_row(value, where: str) -> dict[int, Item]:
        return _row(reader, value, where, states, kind)

    shapes = tuple(
        read_shape(reader, shape, table[shape], f"{key}.{shape}", read_row)
        for shape in SHAPES
        if shape in table
    )
    return NonlinearSpec(
        name=key.split(".", 1)[1],
        key=key,
        description=reader.string(table, "description", key, default=""),
        enabled=reader.boolean(table, "enabled", key, True),
        enters=enters,
        linear=linear,
        constant=_optional(reader, table, "constant", key, 0.0),
        abs_terms=tuple(terms),
        t_on=t_on,
        shapes=shapes,
    )


def _forcing(reader, table, key, equations) -> ForcingSpec:
    table = reader.table(table, key)
    if "enters" not in table:
        raise reader.fail(f"{key}.enters", "missing key")
    enters = _row(reader, table["enters"], f"{key}.enters", equations, "first_order")
    return read_forcing(reader, table, key, enters)
