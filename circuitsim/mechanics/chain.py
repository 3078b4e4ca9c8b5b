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

from circuitsim.mechanics.families import (
    matrices,
    matrix_text,
    model_head,
    model_tail,
    sine_forcing,
)

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
        entries = []
        for i in range(masses):
            row = {i: f"2 * {symbol}" if i < masses - 1 else symbol}
            row.update({j: f"-{symbol}" for j in (i - 1, i + 1) if 0 <= j < masses})
            entries.append(row)
        return matrix_text(entries, masses)

    lines = model_head(
        f"A chain of {masses} masses with a dead-zone contact on each "
        "(circuitsim.mechanics.chain).",
        f"chain{masses}",
        f"chain of {masses} masses, a dead-zone contact on each",
        names,
        PARAMETERS,
    )
    lines += matrices(masses, tridiagonal("c"), tridiagonal("k"))
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
    lines += sine_forcing("drive", "F0", "f", names)
    lines += model_tail(names[0], t_stop)
    return "\n".join(lines)
