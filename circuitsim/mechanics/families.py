"""Shared pieces of the model files of families of any size (chain.py, lattice.py).

Each family writes its model file's TOML text (docs/model.md) line by line; the parts that do
not depend on the family's coupling or terms are here: the head (comment, ``[model]``,
``[coordinates]``, ``[parameters]``), a matrix from its entries, a sine forcing group and the
tail (``[initial]``, ``[circuit]``).
"""

from __future__ import annotations


def model_head(
    comment: str, name: str, description: str, names: list[str], parameters: dict
) -> list[str]:
    """The lines up to the parameters of a second-order model of coordinates ``names`` (m).

    ``parameters`` maps a name to (value, unit, description).
    """
    lines = [
        f"# {comment}",
        "",
        "[model]",
        f'name = "{name}"',
        f'description = "{description}"',
        'kind = "second_order"',
        "",
        "[coordinates]",
        "names = [" + ", ".join(f'"{n}"' for n in names) + "]",
        "units = [" + ", ".join('"m"' for _ in names) + "]",
        "",
        "[parameters]",
    ]
    for key, (value, unit, about) in parameters.items():
        lines.append(f'{key} = {{ value = {value!r}, unit = "{unit}", description = "{about}" }}')
    return lines


def matrix_text(entries: list[dict[int, str]], size: int) -> str:
    """A ``size`` x ``size`` matrix's TOML text: row i holds ``entries[i]`` (column -> the
    expression, quoted here), 0 elsewhere."""
    rows = []
    for row_entries in entries:
        row = ["0"] * size
        for column, expression in row_entries.items():
            row[column] = f'"{expression}"'
        rows.append("[" + ", ".join(row) + "]")
    return "[\n    " + ",\n    ".join(rows) + ",\n]"


def matrices(masses: int, damping: str, stiffness: str) -> list[str]:
    """``[matrices]``: M diagonal (each mass ``m``), C and K as given (:func:`matrix_text`)."""
    mass = matrix_text([{i: "m"} for i in range(masses)], masses)
    return ["", "[matrices]", f"M = {mass}", f"C = {damping}", f"K = {stiffness}"]


def sine_forcing(group: str, amplitude: str, frequency: str, entered: list[str]) -> list[str]:
    """A ``[forcing.GROUP]`` sine of force (N) entering each equation of ``entered`` once."""
    return [
        "",
        f"[forcing.{group}]",
        f'amplitude = "{amplitude}"',
        'unit = "N"',
        f'frequency = "{frequency}"',
        "enters = { " + ", ".join(f"{n} = 1" for n in entered) + " }",
    ]


def model_tail(first: str, t_stop: float) -> list[str]:
    """``[initial]`` (``first`` at 2 cm, the rest at rest) and ``[circuit] t_stop`` (s)."""
    return ["", "[initial]", f"{first} = 0.02", "", "[circuit]", f"t_stop = {float(t_stop)!r}", ""]
