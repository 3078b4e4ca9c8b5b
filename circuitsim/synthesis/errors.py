"""Errors raised by the translator."""


class SynthesisError(ValueError):
    """A model cannot be turned into a circuit as asked (bad option, unrealizable term)."""
