"""A second family of models of any size: a 2-D lattice of masses with one-sided stops.

Where the chain (:mod:`circuitsim.mechanics.chain`) couples each mass to two neighbours and
gives it a symmetric dead zone, the lattice couples each mass to up to four, in a grid of R rows
and C columns (R the largest divisor of N not above sqrt(N): 1 x 2, 2 x 2, 2 x 4, 4 x 4 ...),
and its piecewise-linear terms are one-sided:

- a *floor* under every mass: a stop of stiffness ks that closes when the mass falls below -g
  (one abs term of one state, F = ks min(x + g, 0) = (ks/2)(x + g) - (ks/2)|x + g|);
- a *bumper* between every mass and its right-hand neighbour in the row: a stop of stiffness kb
  that closes when the left mass closes the gap h to it (one abs term of two states, entering
  both equations with opposite signs, u = x_left - x_right,
  F = kb max(u - h, 0) = (kb/2)(u - h) + (kb/2)|u - h|).

Each mass has a spring k0 and a dashpot c0 to ground and a spring k and a dashpot c to each
grid neighbour:

    m x_i'' + c0 x_i' + k0 x_i + sum_{j ~ i} [c (x_i' - x_j') + k (x_i - x_j)]
        + F_floor(x_i) + sum of the bumpers on i = drive_i(t),

driven in a checkerboard: the masses with even row + column by F0 sin(2 pi f t), the odd ones by
F1 sin(2 pi f1 t) (two frequencies, so that neighbours move against each other and every
bumper and floor opens and closes during a run). About 2 N abs terms, as many as the chain's,
but more coupling per mass and terms of two states.

Models are data: :func:`lattice_model_text` returns the model file's TOML text (docs/model.md).
Used by benchmarks/bench_scaling.py (``--family lattice``) and by tests.
"""

from __future__ import annotations

import math

from circuitsim.mechanics import families

PARAMETERS = {
    "m": (1.0, "kg", "mass of each body"),
    "k0": (40.0, "N/m", "spring to ground"),
    "c0": (0.3, "N s/m", "dashpot to ground"),
    "k": (20.0, "N/m", "spring between grid neighbours"),
    "c": (0.3, "N s/m", "dashpot between grid neighbours"),
    "ks": (400.0, "N/m", "floor stiffness"),
    "g": (0.03, "m", "floor depth below rest"),
    "kb": (300.0, "N/m", "bumper stiffness"),
    "h": (0.02, "m", "bumper gap"),
    "F0": (4.0, "N", "force amplitude on the even masses"),
    "f": (1.2, "Hz", "force frequency on the even masses"),
    "F1": (3.0, "N", "force amplitude on the odd masses"),
    "f1": (0.9, "Hz", "force frequency on the odd masses"),
}


def lattice_shape(masses: int) -> tuple[int, int]:
    """Rows and columns of the grid of ``masses`` masses: R the largest divisor <= sqrt(N)."""
    if masses < 1:
        raise ValueError(f"a lattice needs at least one mass, got {masses}")
    rows = max(r for r in range(1, math.isqrt(masses) + 1) if masses % r == 0)
    return rows, masses // rows


def lattice_model_text(masses: int, t_stop: float = 5.0) -> str:
    """The model file (TOML text) of a lattice of ``masses`` masses.

    Parameters
    ----------
    masses : int
        N >= 1 (fewer raises ValueError), laid out as :func:`lattice_shape`; the model has
        2 N states (x1..xN in metres, row by row, and their rates), N floors and R (C - 1)
        bumpers.
    t_stop : float
        Model seconds, written as the file's ``[circuit] t_stop``.
    """
    rows, columns = lattice_shape(masses)
    names = [f"x{i + 1}" for i in range(masses)]

    def neighbours(i: int) -> list[int]:
        r, col = divmod(i, columns)
        around = [(r - 1, col), (r + 1, col), (r, col - 1), (r, col + 1)]
        return [a * columns + b for a, b in around if 0 <= a < rows and 0 <= b < columns]

    def matrix(ground: str, coupling: str) -> str:
        entries = []
        for i in range(masses):
            around = neighbours(i)
            row = {i: f"{ground} + {len(around)} * {coupling}" if around else ground}
            row.update({j: f"-{coupling}" for j in around})
            entries.append(row)
        return families.matrix_text(entries, masses)

    lines = families.model_head(
        f"A {rows} x {columns} lattice of masses with one-sided stops "
        "(circuitsim.mechanics.lattice).",
        f"lattice{masses}",
        f"{rows} x {columns} lattice of masses, a floor under each, bumpers along the rows",
        names,
        PARAMETERS,
    )
    lines += families.matrices(masses, matrix("c0", "c"), matrix("k0", "k"))
    for name in names:
        lines += [
            "",
            f"[nonlinear.floor_{name}]",
            f"enters = {{ {name} = 1 }}",
            f'linear = {{ {name} = "ks / 2" }}',
            'constant = "ks * g / 2"',
            f'abs = [{{ gain = "-ks / 2", row = {{ {name} = 1 }}, offset = "g" }}]',
        ]
    for i in range(masses):
        if i % columns == columns - 1:
            continue
        left, right = names[i], names[i + 1]
        lines += [
            "",
            f"[nonlinear.bumper_{left}_{right}]",
            f"enters = {{ {left} = 1, {right} = -1 }}",
            f'linear = {{ {left} = "kb / 2", {right} = "-kb / 2" }}',
            'constant = "-kb * h / 2"',
            f'abs = [{{ gain = "kb / 2", row = {{ {left} = 1, {right} = -1 }}, offset = "-h" }}]',
        ]
    parity = [sum(divmod(i, columns)) % 2 for i in range(masses)]
    even = [n for n, odd in zip(names, parity, strict=True) if not odd]
    odd = [n for n, odd in zip(names, parity, strict=True) if odd]
    lines += families.sine_forcing("drive_even", "F0", "f", even)
    if odd:  # a single mass has no odd neighbour
        lines += families.sine_forcing("drive_odd", "F1", "f1", odd)
    lines += families.model_tail(names[0], t_stop)
    return "\n".join(lines)
