"""A family of models of any size: a chain of N masses, each with a dead-zone contact.

The chain (ground - k - m1 - k - m2 - ... - mN, each spring with a dashpot c) has a symmetric
gap stop at every mass (the gap oscillator's contact, tests/synthesis/models/gap_oscillator.toml)
and a sinusoidal force on every mass, so that every contact closes during a run:

    m x_i'' + c (2 x_i' - x_{i-1}' - x_{i+1}') + k (2 x_i - x_{i-1} - x_{i+1}) + F_g(x_i)
        = F0 sin(2 pi f t)     (the last mass has one neighbour: 1 instead of 2),
    F_g(x) = kg x - (kg/2)(|x + d| - |x - d|)    (0 inside |x| <= d).

Models are data: :func:`chain_model_text` returns the model file's TOML text (docs/model.md),
which is written to a file and read with :func:`~circuitsim.mechanics.load_model` like any
other model. Used by benchmarks/bench_scaling.py (how the engines scale with circuit size) and
by tests.
"""

from __future__ import annotations

# the gap oscillator's values (tests/synthesis/models/gap_oscillator.toml): contact at 5 cm,
# stops 10x stiffer than the chain's springs
PARAMETERS = {
    "m": (1.0, "kg", "mass of each body"),
    "c": (0.6, "N s/m", "dashpot between neighbours"),
    "k": (40.0, "N/m", "spring between neighbours"),
    "kg": (400.0, "N/m", "stop stiffness"),
    "d": (0.05, "m", "half gap"),
    "F0": (4.0, "N", "force amplitude on each mass"),
    "f": (1.2, "Hz", "force frequency"),
}


def chain_model_text(masses: int, t_stop: float = 5.0) -> str:
    """The model file (TOML text) of a chain of ``masses`` masses with a contact on each.

    Parameters
    ----------
    masses : int
        N >= 1: the model has 2 N states (x1..xN in metres and their rates) and 2 N abs()
        terms (one dead zone per mass).
    t_stop : float
        The ``[circuit] t_stop`` hint, model seconds.

    Raises
    ------
    ValueError
        ``masses`` below 1.
    """
    if masses < 1:
        raise ValueError(f"a chain needs at least one mass, got {masses}")
    names = [f"x{i + 1}" for i in range(masses)]

    def tridiagonal(symbol: str) -> str:
        rows = []
        for i in range(masses):
            row = ["0"] * masses
            row[i] = f'"2 * {symbol}"' if i < masses - 1 else f'"{symbol}"'
            if i > 0:
                row[i - 1] = f'"-{symbol}"'
            if i < masses - 1:
                row[i + 1] = f'"-{symbol}"'
            rows.append("[" + ", ".join(row) + "]")
        return "[\n    " + ",\n    ".join(rows) + ",\n]"

    mass_rows = []
    for i in range(masses):
        row = ["0"] * masses
        row[i] = '"m"'
        mass_rows.append("[" + ", ".join(row) + "]")
    lines = [
        f"# A chain of {masses} masses with a dead-zone contact on each "
        "(circuitsim.mechanics.chain).",
        "",
        "[model]",
        f'name = "chain{masses}"',
        f'description = "chain of {masses} masses, a dead-zone contact on each"',
        'kind = "second_order"',
        "",
        "[coordinates]",
        "names = [" + ", ".join(f'"{n}"' for n in names) + "]",
        "units = [" + ", ".join('"m"' for _ in names) + "]",
        "",
        "[parameters]",
    ]
    for name, (value, unit, description) in PARAMETERS.items():
        lines.append(
            f'{name} = {{ value = {value!r}, unit = "{unit}", description = "{description}" }}'
        )
    lines += [
        "",
        "[matrices]",
        "M = [\n    " + ",\n    ".join(mass_rows) + ",\n]",
        "C = " + tridiagonal("c"),
        "K = " + tridiagonal("k"),
    ]
    for name in names:
        lines += [
            "",
            f"[nonlinear.contact_{name}]",
            f"enters = {{ {name} = 1 }}",
            f'linear = {{ {name} = "kg" }}',
            "abs = [",
            f'    {{ gain = "-kg / 2", row = {{ {name} = 1 }}, offset = "d" }},',
            f'    {{ gain = "kg / 2", row = {{ {name} = 1 }}, offset = "-d" }},',
            "]",
        ]
    lines += [
        "",
        "[forcing.drive]",
        'amplitude = "F0"',
        'unit = "N"',
        'frequency = "f"',
        "enters = { " + ", ".join(f"{n} = 1" for n in names) + " }",
        "",
        "[initial]",
        f"{names[0]} = 0.02",
        "",
        "[circuit]",
        f"t_stop = {float(t_stop)!r}",
        "",
    ]
    return "\n".join(lines)
