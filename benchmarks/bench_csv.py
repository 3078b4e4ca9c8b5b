"""The CSV writer against numpy's savetxt on a table of a TL074 wheelset run's shape.

    python benchmarks/bench_csv.py [ROWS COLUMNS]

Prints the best of three wall and CPU times of each (on a loaded machine the CPU time is
the steadier figure) and
checks that both texts read back to the same floats.
"""

from __future__ import annotations

import io
import sys
import time

import numpy as np

from circuitsim.solver.float_text import table_text


def best_of(runs: int, work) -> tuple[float, float, object]:
    """(best wall time, best CPU time of this process, s; the last result)."""
    wall = cpu = np.inf
    result = None
    for _ in range(runs):
        started, started_cpu = time.perf_counter(), time.process_time()
        result = work()
        wall = min(wall, time.perf_counter() - started)
        cpu = min(cpu, time.process_time() - started_cpu)
    return wall, cpu, result


def savetxt(table: np.ndarray) -> bytes:
    text = io.StringIO()
    np.savetxt(text, table, delimiter=",", fmt="%.17g")
    return text.getvalue().encode()


def main() -> None:
    rows, columns = (int(a) for a in sys.argv[1:3]) if len(sys.argv) > 2 else (15_018, 237)
    rng = np.random.default_rng(1)
    table = rng.standard_normal((rows, columns)) * 10.0 ** rng.integers(-12, 3, (rows, columns))
    table_text(table[:2])  # compiled or loaded from the cache, not timed
    ours, ours_cpu, text = best_of(3, lambda: table_text(table))
    numpy_time, numpy_cpu, reference = best_of(3, lambda: savetxt(table))
    same = np.array_equal(
        np.loadtxt(io.BytesIO(text), delimiter=","),
        np.loadtxt(io.BytesIO(reference), delimiter=","),
    )
    print(
        f"{rows} x {columns}: float_text {ours:.3f} s (CPU {ours_cpu:.3f} s), numpy.savetxt "
        f"{numpy_time:.3f} s (CPU {numpy_cpu:.3f} s), ratio {numpy_time / ours:.1f}, "
        f"same values read back: {same}"
    )


if __name__ == "__main__":
    main()
