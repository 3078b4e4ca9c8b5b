"""Circuit waveforms against the model's direct solution: mapping, metrics, the paper's figures.

``map_waveforms`` turns any engine's node voltages into physical state traces through the scale
map; ``compare_traces`` resamples circuit and reference onto one grid and measures each state
(%NRMSD, max abs error, peak ratio, dominant-frequency ratio, phase lag) against
``Thresholds``, returning a ``Comparison``.
"""

from circuitsim.compare.comparison import (
    Comparison,
    StateMetrics,
    Thresholds,
    compare_traces,
    measure,
)
from circuitsim.compare.errors import ComparisonError
from circuitsim.compare.mapping import common_grid, map_waveforms, resample

__all__ = [
    "Comparison",
    "ComparisonError",
    "StateMetrics",
    "Thresholds",
    "common_grid",
    "compare_traces",
    "map_waveforms",
    "measure",
    "resample",
]
