"""Shorthands of ``[nonlinear.NAME]``: dead zone, saturation, breakpoint table, fitted function.

Each is a function ``f(u)`` of one argument ``u = row . x + offset`` and compiles to the abs()
form every room already handles (docs/model.md)::

    f(u) = a u + c + sum_i g_i |u - b_i|

For slopes ``s_0 .. s_N`` between breakpoints ``b_1 < .. < b_N``: ``a = (s_0 + s_N) / 2``,
``g_i = (s_i - s_{i-1}) / 2`` and ``c`` fixes the value at one point. So

* ``deadzone`` (half-width eta, slope k outside): ``k u - (k/2)(|u + eta| - |u - eta|)``,
  the wheelset's flange form, so the translator's dead-zone block still recognizes it;
* ``saturation`` (limit L, slope k inside): ``(k/2)(|u + L| - |u - L|)``, i.e. k clip(u, -L, L);
* ``table``: the slopes and breakpoints as given, ``f(0) = 0``;
* ``fit``: a smooth expression of ``u`` over a stated range, replaced by the piecewise-linear
  curve of :mod:`circuitsim.mechanics.pwlfit` within a stated maximum error.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from circuitsim.mechanics.expressions import ExpressionError, Item, evaluate_on_grid
from circuitsim.mechanics.pwlfit import (
    MAX_SEGMENTS,
    FitError,
    PiecewiseLinearFit,
    fit_piecewise_linear,
)
from circuitsim.mechanics.system import AbsTerm

SHAPES = {
    "deadzone": ("eta", "slope"),
    "saturation": ("limit", "slope"),
    "table": ("breakpoints", "slopes"),
    "fit": ("function", "range", "max_error"),
}
_OPTIONAL = {"fit": ("variable", "max_segments", "exact_at")}


@dataclass(frozen=True)
class ShapeSpec:
    """One shorthand as written in ``[nonlinear.NAME]`` (still symbolic).

    Attributes
    ----------
    kind : str
        ``"deadzone"``, ``"saturation"``, ``"table"`` or ``"fit"``.
    key : str
        ``"nonlinear.NAME.KIND"``, for errors.
    row : dict of int to Item
        The argument's weights on the states.
    offset : Item
        Added to ``row . x``.
    values : dict of str to Item or tuple of Item
        The kind's own entries (``eta``, ``slopes`` ...).
    variable : str
        ``fit``: the name of the argument in ``function``.
    max_segments : int
        ``fit``: most pieces allowed.
    """

    kind: str
    key: str
    row: dict[int, Item]
    offset: Item
    values: dict
    variable: str = "u"
    max_segments: int = MAX_SEGMENTS


def read_shape(reader, kind: str, table, key: str, read_row: Callable) -> ShapeSpec:
    """Check one shorthand table; ``read_row(value, key)`` reads a vector over the states."""
    table = reader.table(table, key)
    required = SHAPES[kind]
    reader.check_keys(table, key, ("row", "offset") + required + _OPTIONAL.get(kind, ()))
    for name in ("row",) + required:
        if name not in table:
            raise reader.fail(f"{key}.{name}", "missing key")
    values: dict = {}
    for name in required:
        value, where = table[name], f"{key}.{name}"
        if name in ("breakpoints", "slopes", "range", "exact_at"):
            if not isinstance(value, list) or not value:
                raise reader.fail(where, "wrong type: expected a non-empty array")
            values[name] = tuple(reader.expression(v, f"{where}[{i}]") for i, v in enumerate(value))
        else:
            values[name] = reader.expression(value, where)
    if kind == "table" and len(values["slopes"]) != len(values["breakpoints"]) + 1:
        raise reader.fail(
            f"{key}.slopes",
            f"wrong length: {len(values['breakpoints'])} breakpoints need "
            f"{len(values['breakpoints']) + 1} slopes (below, between and above them), got "
            f"{len(values['slopes'])}",
        )
    if kind == "fit" and len(values["range"]) != 2:
        raise reader.fail(f"{key}.range", "wrong length: expected [lower, upper]")
    if "exact_at" in table:  # an empty array is allowed: no exact point
        value, where = table["exact_at"], f"{key}.exact_at"
        if not isinstance(value, list):
            raise reader.fail(where, f"wrong type: expected an array, got {value!r}")
        items = (reader.expression(v, f"{where}[{i}]") for i, v in enumerate(value))
        values["exact_at"] = tuple(items)
    variable = table.get("variable", "u")
    if not isinstance(variable, str) or not variable.isidentifier():
        raise reader.fail(f"{key}.variable", f"expected a name, got {variable!r}")
    segments = table.get("max_segments", MAX_SEGMENTS)
    if isinstance(segments, bool) or not isinstance(segments, int) or not 1 <= segments <= 200:
        raise reader.fail(f"{key}.max_segments", f"expected an integer 1..200, got {segments!r}")
    offset = reader.expression(table.get("offset", 0.0), f"{key}.offset")
    row = read_row(table["row"], f"{key}.row")
    return ShapeSpec(kind, key, row, offset, values, variable, segments)


@dataclass(frozen=True)
class CompiledShape:
    """A shorthand in abs() form, in the units of ``u`` and ``f``.

    Attributes
    ----------
    slope : float
        ``a``: the linear part's weight on ``u``.
    constant : float
        ``c``.
    kinks : tuple of (float, float)
        ``(g_i, b_i)``: the terms ``g_i |u - b_i|``.
    fit : PiecewiseLinearFit or None
        For ``fit``: the curve, its breakpoints and its error bound.
    """

    slope: float
    constant: float
    kinks: tuple[tuple[float, float], ...]
    fit: PiecewiseLinearFit | None = None

    def __call__(self, u: np.ndarray | float) -> np.ndarray:
        """f(u) in the abs() form."""
        u = np.asarray(u, dtype=float)
        total = self.slope * u + self.constant
        for gain, breakpoint in self.kinks:
            total = total + gain * np.abs(u - breakpoint)
        return total

    def abs_terms(self, row: np.ndarray, offset: float) -> tuple[np.ndarray, float, list]:
        """(linear part over the states, constant, AbsTerms) for u = row . x + offset."""
        linear = self.slope * row
        constant = self.slope * offset + self.constant
        terms = [AbsTerm(gain, row.copy(), offset - b) for gain, b in self.kinks if gain]
        return linear, constant, terms


def piecewise_linear(
    breakpoints, slopes, at: float = 0.0, value: float = 0.0, fit=None
) -> CompiledShape:
    """abs() form of the continuous curve with ``slopes`` between ``breakpoints``.

    Parameters
    ----------
    breakpoints : sequence of float, shape (N,)
        Increasing.
    slopes : sequence of float, shape (N + 1,)
        Below the first breakpoint, between consecutive ones, above the last.
    at, value : float
        The curve passes through ``(at, value)``.
    """
    b = np.asarray(breakpoints, dtype=float)
    s = np.asarray(slopes, dtype=float)
    slope = 0.5 * (s[0] + s[-1])
    kinks = tuple(zip((0.5 * np.diff(s)).tolist(), b.tolist(), strict=True))
    constant = value - slope * at - sum(g * abs(at - bk) for g, bk in kinks)
    return CompiledShape(float(slope), float(constant), kinks, fit)


def compile_shape(shape: ShapeSpec, value: Callable[[Item], float], env: Mapping) -> CompiledShape:
    """Evaluate a shorthand at given parameters (``value(item)`` evaluates one entry).

    Raises
    ------
    ShapeError
        A value out of its domain (eta <= 0, breakpoints not increasing, no fit within the
        error ...), with its key; the caller makes it a ModelError.
    """
    v = shape.values
    key = shape.key
    if shape.kind == "deadzone":
        eta, k = value(v["eta"]), value(v["slope"])
        _require(eta > 0, f"{key}.eta", f"the half-width must be > 0, got {eta:g}")
        return piecewise_linear([-eta, eta], [k, 0.0, k])
    if shape.kind == "saturation":
        limit, k = value(v["limit"]), value(v["slope"])
        _require(limit > 0, f"{key}.limit", f"the limit must be > 0, got {limit:g}")
        return piecewise_linear([-limit, limit], [0.0, k, 0.0])
    if shape.kind == "table":
        b = [value(item) for item in v["breakpoints"]]
        _require(
            all(np.diff(b) > 0), f"{key}.breakpoints",
            f"must increase strictly, got {', '.join(f'{x:g}' for x in b)}",
        )  # fmt: skip
        return piecewise_linear(b, [value(item) for item in v["slopes"]])
    return _fitted(shape, value, env)


def _fitted(shape: ShapeSpec, value: Callable[[Item], float], env: Mapping) -> CompiledShape:
    v, key = shape.values, shape.key
    _require(
        shape.variable not in env, f"{key}.variable",
        f"{shape.variable!r} is also a parameter or coefficient: name the argument otherwise "
        "with variable = \"...\"",
    )  # fmt: skip
    lower, upper = (value(item) for item in v["range"])
    bound = value(v["max_error"])
    if "exact_at" in v:
        exact = tuple(value(item) for item in v["exact_at"])
    else:  # the curve passes through f(0): no spurious force at rest
        exact = (0.0,) if lower <= 0.0 <= upper else ()
    function = v["function"]
    numbers = {name: float(env[name]) for name in function.expression.names if name in env}
    cache_key = (function.expression.text, shape.variable, lower, upper, bound, exact,
                 shape.max_segments, tuple(sorted(numbers.items())))  # fmt: skip
    if cache_key in _FITS:
        return _FITS[cache_key]

    def f(u: np.ndarray) -> np.ndarray:
        try:
            return evaluate_on_grid(function.expression, numbers, shape.variable, u)
        except ExpressionError as exc:
            raise ShapeError(function.key, f"bad expression: {exc}") from None

    try:
        fit = fit_piecewise_linear(f, lower, upper, bound, shape.max_segments, exact)
    except FitError as exc:
        raise ShapeError(key, str(exc)) from None
    fit = replace(fit, function=function.expression.text)
    compiled = piecewise_linear(
        fit.breakpoints, fit.slopes, at=fit.knots[0], value=fit.values[0], fit=fit
    )
    if len(_FITS) > 256:  # sweeps fit once per parameter value; keep the memory bounded
        _FITS.clear()
    _FITS[cache_key] = compiled
    return compiled


_FITS: dict[tuple, CompiledShape] = {}


class ShapeError(ValueError):
    """A shorthand's value is out of its domain; ``key`` and ``message`` say where and why."""

    def __init__(self, key: str, message: str):
        super().__init__(f"{key}: {message}")
        self.key = key
        self.message = message


def _require(condition: bool, key: str, message: str) -> None:
    if not condition:
        raise ShapeError(key, message)


def fit_summaries(system) -> list[str]:
    """One line per fitted function of ``system``'s terms (``fit TERM: ...``), for reports."""
    return [f"fit {term.name}: {fit.summary()}" for term in system.nonlinear for fit in term.fits]
