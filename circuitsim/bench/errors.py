"""The bench's typed error."""

from __future__ import annotations


class BenchError(ValueError):
    """A knob value, a pushed state or a request the bench refuses, with what is wrong.

    The HTTP API answers it with status 400 and its message; the running circuit is left as
    it was.
    """
