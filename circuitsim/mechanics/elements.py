"""Models from elements: masses, springs, dampers, creep and contacts between coordinates.

``[elements]`` of a second-order model file (docs/model.md, "Elements") lists the parts of a
mechanism instead of its matrices. Each element acts on a linear combination of the
coordinates written as an expression (``deflection = "yb1 - yc - l*psic + h*phic"``: lever
arms and geometry factors are parameters multiplying coordinates), and each adds its terms to
M, C, K (d the deflection's weights on the coordinates, q the coordinates)::

    masses         m on coordinate i                         M[i][i] += m
    springs        stiffness k >= 0, deflection d . q        K += k d d^T
    dampers        damping c >= 0, deflection d . q          C += c d d^T
    gravitational  stiffness g of either sign, d . q         K += g d d^T
    creep          coefficient f >= 0, speed V > 0, along a . q, creepage w . q:
                   the force -f (a . q'/V + w . q) acts on a . q
                                                             C += (f/V) a a^T, K += f a w^T
    contacts       stiffness k >= 0, clearance eta > 0, deflection d . q: the force
                   k deadzone(d . q, eta) acts on d . q      a [nonlinear] group

The assembly is symbolic: each entry of M, C, K becomes one expression, the sum of its
elements' products, so the loaded model is the matrix form with every parameter still a
parameter (``--param``, ``--speed``, the bench's knobs and derived parameters work as for a
file that types its matrices). A contact becomes a ``[nonlinear.NAME]`` group with the
``deadzone`` shorthand, the form the translator's dead-zone block recognizes. ``[matrices]``
may be given too: its M, C, K are added to the assembly and its F kept.

Values are checked where they are written: a negative spring or damper, a mass that is not
positive, a clearance that is not positive (at the file's defaults, in every coefficient
set), an unknown coordinate, a deflection that is not linear in the coordinates or names no
coordinate, a coordinate without a mass.
"""

from __future__ import annotations

from collections.abc import Callable

from circuitsim.mechanics.expressions import Expression, ExpressionError, Item, parse
from circuitsim.mechanics.modelfile import NonlinearSpec
from circuitsim.mechanics.parameters import evaluate_parameters
from circuitsim.mechanics.shapes import ShapeSpec
from circuitsim.mechanics.tomlfile import TableReader, check_identifier

#: element kind -> (its value keys, its linear-form keys, optional keys)
KINDS = {
    "springs": (("stiffness",), ("deflection",), ()),
    "dampers": (("damping",), ("deflection",), ()),
    "gravitational": (("stiffness",), ("deflection",), ()),
    "creep": (("coefficient", "speed"), ("along",), ("creepage",)),
    "contacts": (("stiffness", "clearance"), ("deflection",), ("enabled",)),
}
# which values must be positive (> 0) or not negative (>= 0): the rest may take either sign
_POSITIVE = {("creep", "speed"), ("contacts", "clearance")}
_NOT_NEGATIVE = {
    ("springs", "stiffness"),
    ("dampers", "damping"),
    ("creep", "coefficient"),
    ("contacts", "stiffness"),
}
_ZERO, _ONE = ("num", 0.0), ("num", 1.0)
Tree = tuple
Form = dict[int, Tree]  # coordinate index -> coefficient (an expression tree)


def read_elements(
    reader: TableReader,
    document: dict,
    coordinates: tuple[str, ...],
    parameters: dict,
    coefficient_sets: dict,
    matrices: dict,
    nonlinear: dict[str, NonlinearSpec],
) -> tuple[dict, dict[str, NonlinearSpec]]:
    """Assemble ``[elements]`` into the matrices and nonlinear groups of the model.

    Parameters
    ----------
    reader : TableReader
        The model file's reader (errors name the file and the dotted key).
    document : dict
        The whole TOML document.
    coordinates : tuple of str
        The model's coordinates (the rows and columns of M, C, K).
    parameters : dict of str to Parameter
        The file's parameters (for the checks at their defaults).
    coefficient_sets : dict
        Set name -> ((coefficient, Item), ...), as read.
    matrices : dict
        ``[matrices]`` as read (may be empty): its M, C, K are added to the assembly.
    nonlinear : dict of str to NonlinearSpec
        ``[nonlinear]`` groups as read: a contact may not reuse their names.

    Returns
    -------
    matrices : dict
        M, C, K (lists of rows of Item) and F when ``[matrices]`` gave it.
    nonlinear : dict of str to NonlinearSpec
        ``nonlinear`` followed by one group per contact.

    Raises
    ------
    ModelError
        ``FILE: elements.KIND.NAME.KEY: MESSAGE`` for anything wrong.
    """
    table = reader.table(document.get("elements"), "elements")
    reader.check_keys(table, "elements", ("masses",) + tuple(KINDS))
    size = len(coordinates)
    environments = _environments(reader, parameters, coefficient_sets)
    known = set(parameters) | {c for items in coefficient_sets.values() for c, _ in items}

    def value(entry, key: str, sign: str = "") -> Item:
        return check(reader.expression(entry, key), key, sign)

    def check(item: Item, key: str, sign: str = "") -> Item:
        for set_name, env in environments:
            try:
                number = item.expression(dict(env))
            except ExpressionError as exc:
                raise reader.fail(key, f"bad expression{set_name}: {exc}") from None
            if sign == "positive" and not number > 0:
                raise reader.fail(key, f"must be positive, got {number:g}{set_name}")
            if sign == "not negative" and number < 0:
                hint = " (a signed stiffness is [elements.gravitational])" * key.startswith(
                    "elements.springs."
                )
                raise reader.fail(key, f"must not be negative, got {number:g}{set_name}{hint}")
        return item

    def form(entry, key: str) -> Form:
        item = reader.expression(entry, key)
        weights = linear_form(item.expression.tree, coordinates, known, key, reader.fail)
        for index, tree in weights.items():
            check(Item(key, Expression(_text(tree), tree)), f"{key} ({coordinates[index]})")
        return weights

    mass = _masses(reader, table, coordinates, value)
    # each entry's terms, summed at the end (a balanced sum: a file of thousands of elements
    # on one coordinate stays a shallow tree)
    damping: list[list[list[Tree]]] = [[[] for _ in range(size)] for _ in range(size)]
    stiffness: list[list[list[Tree]]] = [[[] for _ in range(size)] for _ in range(size)]
    contacts: dict[str, NonlinearSpec] = {}
    for kind, (values_of, forms_of, optional) in KINDS.items():
        for name, entry in reader.table(table.get(kind), f"elements.{kind}", False).items():
            key = f"elements.{kind}.{name}"
            check_identifier(reader, name, key)
            entry = reader.table(entry, key)
            reader.check_keys(entry, key, values_of + forms_of + optional + ("description",))
            for needed in values_of + forms_of:
                if needed not in entry:
                    raise reader.fail(f"{key}.{needed}", "missing key")
            description = reader.string(entry, "description", key, default="")
            numbers = {}
            for part in values_of:
                sign = ("positive" if (kind, part) in _POSITIVE else
                        "not negative" if (kind, part) in _NOT_NEGATIVE else "")  # fmt: skip
                numbers[part] = value(entry[part], f"{key}.{part}", sign).expression.tree
            rows = {part: form(entry[part], f"{key}.{part}") for part in forms_of}
            if kind == "springs" or kind == "gravitational":
                _outer(stiffness, numbers["stiffness"], rows["deflection"], rows["deflection"])
            elif kind == "dampers":
                _outer(damping, numbers["damping"], rows["deflection"], rows["deflection"])
            elif kind == "creep":
                along = rows["along"]
                creepage = _creepage(entry, key, form)
                coefficient = numbers["coefficient"]
                _outer(damping, _div(coefficient, numbers["speed"]), along, along)
                _outer(stiffness, coefficient, along, creepage)
            else:
                contacts[name] = _contact(reader, entry, key, name, description, numbers, rows)
                if name in nonlinear:
                    raise reader.fail(key, f"a [nonlinear] group is also named {name!r}")
    assembled = {
        "M": _items(mass, matrices.get("M"), "M", coordinates),
        "C": _items(damping, matrices.get("C"), "C", coordinates),
        "K": _items(stiffness, matrices.get("K"), "K", coordinates),
    }
    if "F" in matrices:
        assembled["F"] = matrices["F"]
    return assembled, {**nonlinear, **contacts}


def _environments(reader: TableReader, parameters: dict, coefficient_sets: dict) -> list:
    """(`` (with coefficient set 'NAME')`` or "", values) for each set, at the defaults."""
    values = evaluate_parameters(parameters, {}, reader.file)
    named = list(coefficient_sets) != ["default"]
    out = []
    for set_name, items in coefficient_sets.items():
        env = dict(values)
        for coefficient, item in items:
            try:
                env[coefficient] = item.expression(dict(env))
            except ExpressionError:
                continue  # the set's own error is reported by the loader, at its key
        out.append((f" (with coefficient set {set_name!r})" if named else "", env))
    return out


def _masses(reader: TableReader, table: dict, coordinates, value) -> list[list[list[Tree]]]:
    """M from ``[elements.masses]``: each coordinate's mass or inertia, positive."""
    masses = reader.table(table.get("masses"), "elements.masses")
    size = len(coordinates)
    mass: list[list[list[Tree]]] = [[[] for _ in range(size)] for _ in range(size)]
    for name, entry in masses.items():
        if name not in coordinates:
            raise reader.fail(
                f"elements.masses.{name}",
                f"unknown coordinate (coordinates: {', '.join(coordinates)})",
            )
        index = coordinates.index(name)
        mass[index][index] = [value(entry, f"elements.masses.{name}", "positive").expression.tree]
    missing = [name for name in coordinates if name not in masses]
    if missing:
        raise reader.fail(
            "elements.masses",
            f"missing mass for {', '.join(missing)} (every coordinate needs a mass or inertia)",
        )
    return mass


def _creepage(entry: dict, key: str, form: Callable) -> Form:
    """The creepage's part from the displacements (``creepage``, default none)."""
    if "creepage" not in entry:
        return {}
    return form(entry["creepage"], f"{key}.creepage")


def _contact(reader, entry, key, name, description, numbers, rows) -> NonlinearSpec:
    """A contact as the ``[nonlinear]`` group it stands for: k deadzone(d . q, eta) on d."""
    deflection = rows["deflection"]
    row = {i: Item(f"{key}.deflection", Expression(_text(t), t)) for i, t in deflection.items()}
    values = {
        "eta": Item(f"{key}.clearance", Expression(_text(numbers["clearance"]),
                                                   numbers["clearance"])),
        "slope": Item(f"{key}.stiffness", Expression(_text(numbers["stiffness"]),
                                                     numbers["stiffness"])),
    }  # fmt: skip
    shape = ShapeSpec("deadzone", key, row, Item(key, parse(0.0)), values)
    return NonlinearSpec(
        name=name,
        key=key,
        description=description or f"contact {name}: a dead zone of its deflection",
        enabled=reader.boolean(entry, "enabled", key, True),
        enters=dict(row),  # the force acts on the deflection (its generalized force)
        linear={},
        constant=Item(key, parse(0.0)),
        abs_terms=(),
        t_on=None,
        shapes=(shape,),
    )


def _outer(target: list[list[list[Tree]]], factor: Tree, left: Form, right: Form) -> None:
    """``target += factor * left right^T`` (symbolically: one more term per entry)."""
    for i, a in left.items():
        for j, b in right.items():
            term = _mul(factor, _mul(a, b))
            if term != _ZERO:
                target[i][j].append(term)


def _sum(terms: list[Tree]) -> Tree:
    """The terms' sum as a balanced tree (depth log2 of their number)."""
    if not terms:
        return _ZERO
    while len(terms) > 1:
        pairs = [_add(terms[k], terms[k + 1]) for k in range(0, len(terms) - 1, 2)]
        terms = pairs + terms[len(pairs) * 2 :]
    return terms[0]


def _items(terms, given, name: str, coordinates) -> list[list[Item]]:
    """Rows of Items: the assembled entries plus those of ``[matrices]`` (if given)."""
    rows = []
    for i, row in enumerate(terms):
        items = []
        for j, entry in enumerate(row):
            tree, key = _sum(entry), f"elements.{name}[{coordinates[i]}][{coordinates[j]}]"
            if given is not None:
                tree = _add(given[i][j].expression.tree, tree)
                key = f"matrices.{name}[{i}][{j}] + {key}"
            items.append(Item(key, Expression(_text(tree), tree)))
        rows.append(items)
    return rows


def linear_form(
    tree: Tree, coordinates: tuple[str, ...], known: set[str], key: str, fail: Callable
) -> Form:
    """The weights of an expression linear in the coordinates: ``a*y1 - b*(y2 + y3)``.

    Parameters
    ----------
    tree : tuple
        A parsed expression (:class:`~circuitsim.mechanics.expressions.Expression`'s tree).
    coordinates : tuple of str
        The names that are coordinates; every other name must be in ``known``.
    known : set of str
        Parameter and coefficient names.
    key : str
        For errors.
    fail : callable
        ``fail(key, message)`` returns the error to raise.

    Returns
    -------
    dict of int to tree
        Coordinate index -> its weight (an expression of parameters), for the coordinates
        the expression names.

    Raises
    ------
    ModelError
        A product of coordinates, a coordinate in a function, power or denominator, a
        constant part, an unknown name, no coordinate at all.
    """
    weights, constant = _linear(tree, coordinates, known, key, fail)
    if not weights:
        raise fail(key, "names no coordinate (coordinates: " + ", ".join(coordinates) + ")")
    if constant is not None:
        raise fail(
            key, f"has a part without a coordinate ({_text(constant)!r}): an element acts on "
            "a linear combination of the coordinates only"
        )  # fmt: skip
    return {coordinates.index(name): weight for name, weight in weights.items()}


def _linear(node: Tree, coordinates, known, key, fail) -> tuple[dict[str, Tree], Tree | None]:
    """(weights by coordinate name, the part without coordinates or None) of ``node``."""
    kind = node[0]
    if kind == "num":
        return {}, (None if node[1] == 0 else node)
    if kind == "name":
        name = node[1]
        if name in coordinates:
            if name in known:
                raise fail(key, f"{name!r} is both a coordinate and a parameter")
            return {name: _ONE}, None
        if name not in known and name != "pi":
            rates = [c for c in coordinates if name == f"{c}_dot"]
            hint = " (write the coordinate: a damper or creep element takes its rate)" * bool(rates)
            raise fail(
                key, f"unknown coordinate or parameter {name!r}{hint} (coordinates: "
                f"{', '.join(coordinates)})"
            )  # fmt: skip
        return {}, node
    if kind == "neg":
        weights, constant = _linear(node[1], coordinates, known, key, fail)
        return {n: _neg(w) for n, w in weights.items()}, _neg(constant) if constant else None
    if kind == "call" or kind == "**":
        parts = node[2] if kind == "call" else node[1:]
        for part in parts:
            if _linear(part, coordinates, known, key, fail)[0]:
                where = f"{node[1]}()" if kind == "call" else "a power"
                raise fail(key, f"not linear in the coordinates: a coordinate inside {where}")
        return {}, node
    left, left_constant = _linear(node[1], coordinates, known, key, fail)
    right, right_constant = _linear(node[2], coordinates, known, key, fail)
    if kind in ("+", "-"):
        sign = _neg if kind == "-" else (lambda tree: tree)
        weights = dict(left)
        for name, weight in right.items():
            weights[name] = _add(weights.get(name, _ZERO), sign(weight))
        if right_constant is None:
            return weights, left_constant
        return weights, _add(left_constant or _ZERO, sign(right_constant))
    if kind == "/":
        if right:
            raise fail(key, "not linear in the coordinates: a coordinate in a denominator")
        if right_constant is None:
            raise fail(key, "division by zero")
        divide = lambda tree: _div(tree, right_constant)  # noqa: E731
        return {n: divide(w) for n, w in left.items()}, (
            divide(left_constant) if left_constant else None
        )
    # a product: one side must be free of coordinates
    if left and right:
        raise fail(key, "not linear in the coordinates: a product of coordinates")
    weights, factor = (left, right_constant) if left else (right, left_constant)
    constant = None
    if left_constant is not None and right_constant is not None:
        constant = _mul(left_constant, right_constant)
    if factor is None:  # times zero
        return {}, constant
    return {n: _mul(w, factor) for n, w in weights.items()}, constant


def _add(a: Tree, b: Tree) -> Tree:
    if a == _ZERO:
        return b
    if b == _ZERO:
        return a
    if b[0] == "neg":
        return ("-", a, b[1])
    return ("+", a, b)


def _neg(a: Tree) -> Tree:
    if a == _ZERO:
        return a
    return a[1] if a[0] == "neg" else ("neg", a)


def _mul(a: Tree, b: Tree) -> Tree:
    if a == _ZERO or b == _ZERO:
        return _ZERO
    if a == _ONE:
        return b
    if b == _ONE:
        return a
    if a[0] == "neg":
        return _neg(_mul(a[1], b))
    if b[0] == "neg":
        return _neg(_mul(a, b[1]))
    return ("*", a, b)


def _div(a: Tree, b: Tree) -> Tree:
    if b == _ONE or a == _ZERO:
        return a
    if a[0] == "neg":
        return _neg(_div(a[1], b))
    return ("/", a, b)


_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2, "neg": 3, "**": 4}


def _text(node: Tree) -> str:
    """The expression text of a tree (for messages), parenthesized where precedence needs."""
    kind = node[0]
    if kind == "num":
        return repr(node[1]).removesuffix(".0")
    if kind == "name":
        return node[1]
    if kind == "call":
        return f"{node[1]}({', '.join(_text(arg) for arg in node[2])})"
    if kind == "neg":
        return "-" + _wrap(node[1], 3, strict=False)
    level = _PRECEDENCE[kind]
    if kind == "**":
        return f"{_wrap(node[1], 5, False)}**{_wrap(node[2], 5, False)}"
    return f"{_wrap(node[1], level, False)} {kind} {_wrap(node[2], level, kind in '-/')}"


def _wrap(node: Tree, level: int, strict: bool) -> str:
    """``node``'s text, in parentheses when it binds less than ``level`` (or as little, if
    ``strict``: the right operand of - and /)."""
    inner = _PRECEDENCE.get(node[0], 6)
    text = _text(node)
    return f"({text})" if inner < level or (strict and inner == level) else text
