"""The swept values of a parameter sweep, from the command line's ``--values`` text.

Kept apart from sweep.py (and its scipy and translator imports) so that the command line can
name the limit in its help without loading them; numpy too is imported only when values are
parsed (building the parser of every verb loaded it, 0.2 s of a ``circuitsim --version``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from circuitsim.compare.errors import ComparisonError

if TYPE_CHECKING:
    import numpy as np

MAX_VALUES = 10_000
"""Most values :func:`parse_values` accepts: each is a circuit simulation of its own."""


def parse_values(text: str, limit: int = MAX_VALUES) -> np.ndarray:
    """``"START:STOP:STEP"`` (STOP included when on the grid) or ``"v1,v2,..."``.

    A STEP longer than STOP - START gives START alone.

    Parameters
    ----------
    text : str
        The ``--values`` text.
    limit : int
        Most values accepted (default :data:`MAX_VALUES`); checked before any array is made.

    Returns
    -------
    ndarray
        The values, finite.

    Raises
    ------
    ComparisonError
        Unparsable text, a non-finite number, a non-positive step, an empty range, or more
        than ``limit`` values.
    """
    import numpy as np

    def fail(problem: str) -> ComparisonError:
        return ComparisonError(f"--values {text!r}: {problem}")

    try:
        if ":" in text:
            start, stop, step = (float(p) for p in text.split(":"))
        else:
            listed = [float(p) for p in text.split(",") if p.strip()]
    except ValueError:
        raise fail(
            "expected START:STOP:STEP with STEP > 0 and STOP >= START, or a comma-separated "
            "list of numbers"
        ) from None
    if ":" in text:
        if not all(math.isfinite(v) for v in (start, stop, step)):
            raise fail("START, STOP and STEP must be finite numbers")
        if not step > 0 or stop < start:
            raise fail("expected START:STOP:STEP with STEP > 0 and STOP >= START")
        steps = (stop - start) / step + 1e-9  # inf when STEP is far too small for the range
        if not steps < limit:
            raise fail(f"more than {limit:,} values; use a larger STEP or a narrower range")
        values = start + step * np.arange(int(math.floor(steps)) + 1)
    else:
        values = np.array(listed, dtype=float)
        if not np.all(np.isfinite(values)):
            raise fail("the values must be finite numbers")
        if values.size > limit:
            raise fail(f"{values.size:,} values, more than {limit:,}")
    if values.size == 0:
        raise fail("no values")
    return values
