"""Circuit waveforms against the model's direct solution: mapping, metrics, the paper's figures.

``map_waveforms`` turns any engine's node voltages into physical state traces through the scale
map; ``compare_traces`` resamples circuit and reference onto one grid and measures each state
(%NRMSD, max abs error, peak ratio, dominant-frequency ratio, phase lag) against
``Thresholds``, returning a ``Comparison``.
"""

# The names below are loaded on first use (PEP 562), not when the package is imported: the
# metrics pull in scipy.interpolate and scipy.signal (about half a second), which a sweep or
# the command line's parser does not need.
_WHERE = {
    "Comparison": "comparison",
    "StateMetrics": "comparison",
    "Thresholds": "comparison",
    "compare_traces": "comparison",
    "measure": "comparison",
    "ComparisonError": "errors",
    "common_grid": "mapping",
    "map_waveforms": "mapping",
    "resample": "mapping",
}


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(f"{__name__}.{_WHERE[name]}"), name)
    globals()[name] = value
    return value


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
