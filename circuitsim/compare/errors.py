"""The comparator's typed error."""

from __future__ import annotations


class ComparisonError(ValueError):
    """Two traces cannot be compared: a state's node is missing, the time ranges do not
    overlap, a trace is empty or not finite ... The message names the state and the problem."""
