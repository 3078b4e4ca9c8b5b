"""A model as data: parameters, coefficient sets, switchable terms; numbers on request.

:func:`load_model` reads a model file (see docs/model.md); :meth:`Model.system` evaluates it at
chosen parameter values and coefficient set and returns the first-order
:class:`~circuitsim.mechanics.system.System` every other room works from.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from circuitsim.mechanics.errors import ModelError
from circuitsim.mechanics.expressions import ExpressionError
from circuitsim.mechanics.modelfile import ForcingSpec, Item, ModelSpec, Parameter, read_model
from circuitsim.mechanics.parameters import evaluate_parameters
from circuitsim.mechanics.shapes import ShapeError, compile_shape
from circuitsim.mechanics.system import (
    AbsTerm,
    Bump,
    PiecewiseLinearInput,
    PiecewiseLinearTerm,
    Sinusoid,
    System,
)

# A mass matrix whose condition number exceeds this is treated as singular: inverting it would
# turn rounding noise into accelerations.
_MAX_CONDITION = 1e12


def load_model(path: str | Path | None = None) -> Model:
    """Load a model file; ``None`` loads the built-in wheelset, ``"bogie"`` a shipped model.

    The file is checked completely, including an evaluation of every coefficient set at the
    default parameters, so later calls to :meth:`Model.system` with the defaults cannot fail.

    Raises
    ------
    ModelError
        Naming the file, the dotted key and what is wrong.
    """
    model = Model(read_model(path))
    for name in model.coefficient_sets:
        everything_on = {group: True for group in model.nonlinear_terms}
        forcing_on = {group: True for group in model.forcing_terms}
        model.system(coefficients=name, nonlinear=everything_on, forcing=forcing_on)
    return model


class Model:
    """A loaded model file.

    Attributes
    ----------
    name, description, kind : str
        From ``[model]``; kind is ``"second_order"`` or ``"first_order"``.
    file : str
        The model file.
    states, units : tuple of str
        State names and SI units in order (second order: coordinates, then their rates
        ``<q>_dot``).
    coordinates : tuple of str
        Second-order coordinates (empty for first-order models).
    parameters : dict of str to float
        Default parameter values.
    parameter_info : dict of str to Parameter
        Defaults with unit and description.
    options : dict of str to str
        Command-line option name -> parameter name (``speed -> V``); ``state`` -> a state
        name (:attr:`default_state`).
    coefficient_sets : tuple of str
        Names of the coefficient sets; ``default_coefficients`` is the one used when none is
        named.
    nonlinear_terms, forcing_terms : dict of str to bool
        Names of the switchable groups and whether each is on by default.
    circuit : dict
        The free-form ``[circuit]`` table.
    time_unit : str
        The unit of the model's time (``"s"``; ``""`` when the time is dimensionless).
    """

    def __init__(self, spec: ModelSpec):
        self.spec = spec
        self.name = spec.name
        self.description = spec.description
        self.kind = spec.kind
        self.file = spec.file
        self.states = spec.states
        self.units = spec.units
        self.coordinates = spec.coordinates
        self.parameter_info: dict[str, Parameter] = dict(spec.parameters)
        self.parameters = {name: p.value for name, p in spec.parameters.items()}
        self.options = dict(spec.options)
        self.coefficient_sets = tuple(spec.coefficient_sets)
        self.default_coefficients = spec.default_coefficients
        self.nonlinear_terms = {name: g.enabled for name, g in spec.nonlinear.items()}
        self.forcing_terms = {name: g.enabled for name, g in spec.forcing.items()}
        self.circuit = spec.circuit
        self.time_unit = spec.time_unit

    def __repr__(self) -> str:
        return f"Model({self.name!r}, kind={self.kind!r}, states={self.states}, file={self.file!r})"

    @property
    def n(self) -> int:
        """Number of states."""
        return len(self.states)

    @property
    def default_state(self) -> str:
        """The state the verbs push (``--y0``) and measure when no ``--state`` is given: the
        one ``[options] state`` names, else the first."""
        return self.options.get("state", self.states[0])

    def state_named(self, name: str | None) -> str:
        """``name`` (a ``--state``), or :attr:`default_state` for None.

        Raises
        ------
        ModelError
            A name that is no state of the model.
        """
        if name is None:
            return self.default_state
        if name not in self.states:
            raise self._fail(
                "--state", f"unknown state {name!r} (states: {', '.join(self.states)})"
            )
        return name

    def with_input_file(self, name: str, path: str) -> Model:
        """This model with forcing group ``name``'s input read from the CSV file ``path``.

        The group keeps its ``enters`` and ``unit``, becomes a ``series`` (time in s, value
        in the group's unit; :func:`~circuitsim.mechanics.forcingfile.series_from_file`) and
        is switched on.

        Raises
        ------
        ModelError
            No forcing group ``name``; a bad file (the error names it and the line).
        """
        from dataclasses import replace

        from circuitsim.mechanics.forcingfile import series_from_file

        if name not in self.spec.forcing:
            known = ", ".join(self.spec.forcing) or "none"
            raise ModelError(
                f"model {self.name} has no forcing group {name!r} (known: {known})",
                key=f"--input {name}",
            )
        forcing = dict(self.spec.forcing)
        forcing[name] = series_from_file(forcing[name], path)
        return Model(replace(self.spec, forcing=forcing))

    def option_parameters(self, values: Mapping[str, float | None]) -> dict[str, float]:
        """Translate command-line option values to parameter values through ``[options]``.

        Parameters
        ----------
        values : dict of option name to float or None
            ``{"speed": 57.0, "freq": None}``; None means "not given" and is skipped.

        Raises
        ------
        ModelError
            An option the model file does not map to a parameter.
        """
        out = {}
        for option, value in values.items():
            if value is None:
                continue
            if option not in self.options:
                mapped = ", ".join(self.options) or "none"
                raise self._fail(
                    f"options.{option}",
                    f"the model has no parameter for --{option} (mapped options: {mapped})",
                )
            out[self.options[option]] = float(value)
        return out

    def _fail(self, key: str | None, message: str) -> ModelError:
        return ModelError(message, file=self.file, key=key)

    def _value(self, item: Item, env: Mapping[str, float], coefficients: str) -> float:
        try:
            return item.expression(dict(env))
        except ExpressionError as exc:
            named = list(self.spec.coefficient_sets) != ["default"]
            where = f" (with coefficient set {coefficients!r})" if named else ""
            raise self._fail(item.key, f"bad expression{where}: {exc}") from None

    def _switches(self, given, defaults: dict[str, bool], what: str) -> dict[str, bool]:
        chosen = dict(defaults)
        for name, on in dict(given or {}).items():
            if name not in defaults:
                known = ", ".join(defaults) or "none"
                raise self._fail(f"{what}.{name}", f"unknown {what} term (known: {known})")
            chosen[name] = bool(on)
        return chosen

    def environment(
        self, coefficients: str | None = None, parameters: Mapping[str, float] | None = None
    ) -> tuple[str, dict[str, float], dict[str, float]]:
        """Parameter values and coefficient values for one evaluation.

        Returns
        -------
        set_name : str
        values : dict of str to float
            The parameters (defaults overridden by ``parameters``).
        coefficient_values : dict of str to float
            The coefficient set evaluated at those parameters, in file order.
        """
        set_name = self.default_coefficients if coefficients is None else coefficients
        if set_name not in self.spec.coefficient_sets:
            raise self._fail(
                "coefficients",
                f"unknown coefficient set {set_name!r} (sets: {', '.join(self.coefficient_sets)})",
            )
        given = {}
        for name, value in dict(parameters or {}).items():
            if name not in self.parameters:
                known = ", ".join(self.parameters) or "none"
                raise self._fail(f"parameters.{name}", f"unknown parameter (known: {known})")
            try:
                given[name] = float(value)
            except (TypeError, ValueError):
                raise self._fail(
                    f"parameters.{name}", f"expected a number, got {value!r}"
                ) from None
            if not np.isfinite(given[name]):
                raise self._fail(f"parameters.{name}", f"must be finite, got {value!r}")
        # parameters written as expressions follow the values given (docs/model.md)
        values = evaluate_parameters(self.spec.parameters, given, self.file)
        env = dict(values)
        coefficient_values = {}
        for name, item in self.spec.coefficient_sets[set_name]:
            coefficient_values[name] = env[name] = self._value(item, env, set_name)
        return set_name, values, coefficient_values

    def system(
        self,
        coefficients: str | None = None,
        parameters: Mapping[str, float] | None = None,
        nonlinear: Mapping[str, bool] | None = None,
        x0: Sequence[float] | Mapping[str, float] | None = None,
        forcing: Mapping[str, bool] | None = None,
    ) -> System:
        """Evaluate the model into a first-order :class:`System`.

        Parameters
        ----------
        coefficients : str, optional
            Coefficient set name (default: the file's ``coefficients.default``).
        parameters : dict of str to float, optional
            Overrides of the parameter defaults, e.g. ``{"V": 55, "f": 3, "a": 0.04}``.
        nonlinear, forcing : dict of str to bool, optional
            Switch named groups on or off (default: each group's ``enabled``). Switched-off
            groups are absent from the System.
        x0 : array_like, shape (n,), or dict of state name to float, optional
            Initial state; default from the file's ``[initial]`` table (missing states 0). A
            dict overrides only the states it names.

        Raises
        ------
        ModelError
            Unknown set, parameter, group or state; an expression that cannot be evaluated;
            a singular mass matrix.
        """
        set_name, values, coefficient_values = self.environment(coefficients, parameters)
        env = {**values, **coefficient_values}
        nonlinear_on = self._switches(nonlinear, self.nonlinear_terms, "nonlinear")
        forcing_on = self._switches(forcing, self.forcing_terms, "forcing")
        spec = self.spec
        n = self.n

        def value(item: Item) -> float:
            return self._value(item, env, set_name)

        def vector(row: dict[int, Item], size: int) -> np.ndarray:
            out = np.zeros(size)
            for index, item in row.items():
                out[index] = value(item)
            return out

        def matrix(name: str, size: int) -> np.ndarray:
            rows = spec.matrices.get(name)
            if rows is None:
                return np.zeros((size, size))
            return np.array([[value(item) for item in row] for row in rows], dtype=float)

        if self.kind == "second_order":
            size = len(self.coordinates)
            mass = matrix("M", size)
            if not np.all(np.isfinite(mass)) or np.linalg.cond(mass) > _MAX_CONDITION:
                raise self._fail(
                    "matrices.M", f"singular mass matrix with coefficient set {set_name!r}"
                )
            inverse = np.linalg.inv(mass)
            A = np.zeros((n, n))
            A[:size, size:] = np.eye(size)
            with np.errstate(over="ignore", invalid="ignore"):  # _check_finite names it
                A[size:, :size] = -inverse @ matrix("K", size)
                A[size:, size:] = -inverse @ matrix("C", size)
            b0 = np.zeros(n)
            if "F" in spec.matrices:
                b0[size:] = inverse @ np.array([value(item) for item in spec.matrices["F"]])

            def lhs_direction(enters: dict[int, Item]) -> np.ndarray:
                # the term sits on the left-hand side: M q'' = ... - e s
                out = np.zeros(n)
                out[size:] = -inverse @ vector(enters, size)
                return out

            def rhs_direction(enters: dict[int, Item]) -> np.ndarray:
                out = np.zeros(n)
                out[size:] = inverse @ vector(enters, size)
                return out

            nonlinear_direction = lhs_direction
        else:
            A = matrix("A", n)
            b0 = np.zeros(n)
            if "b" in spec.matrices:
                b0 = np.array([value(item) for item in spec.matrices["b"]])

            def rhs_direction(enters: dict[int, Item]) -> np.ndarray:
                return vector(enters, n)

            nonlinear_direction = rhs_direction

        terms = []
        for name, group in spec.nonlinear.items():
            if not nonlinear_on[name]:
                continue
            abs_terms = [
                AbsTerm(gain=value(t.gain), row=vector(t.row, n), offset=value(t.offset))
                for t in group.abs_terms
            ]
            linear, constant = vector(group.linear, n), value(group.constant)
            fits = []
            for shape in group.shapes:  # deadzone, saturation, table, fit: more abs terms
                try:
                    compiled = compile_shape(shape, value, env)
                except ShapeError as exc:
                    raise self._fail(exc.key, exc.message) from None
                more = compiled.abs_terms(vector(shape.row, n), value(shape.offset))
                linear, constant = linear + more[0], constant + more[1]
                abs_terms += more[2]
                fits += [compiled.fit] if compiled.fit else []
            terms.append(
                PiecewiseLinearTerm(
                    name=name,
                    direction=nonlinear_direction(group.enters),
                    linear=linear,
                    abs_terms=tuple(abs_terms),
                    constant=constant,
                    t_on=None if group.t_on is None else value(group.t_on),
                    fits=tuple(fits),
                )
            )
        sources = []
        for name, group in spec.forcing.items():
            if forcing_on[name]:
                sources.extend(_inputs(group, rhs_direction(group.enters), value, self._fail))
        self._check_finite(A, b0, terms, sources, set_name)
        return System(
            name=self.name,
            states=self.states,
            units=self.units,
            A=A,
            b0=b0,
            nonlinear=tuple(terms),
            forcing=tuple(sources),
            x0=self._initial(x0, value),
            parameters=values,
            circuit_hints=dict(self.circuit),
            coefficients=coefficient_values,
            coefficient_set=set_name,
        )

    def _check_finite(self, A, b0, terms, sources, set_name: str) -> None:
        """Refuse a System with an infinite or NaN number in it.

        Every expression evaluates to a finite value, but their products need not: M = 1e-300
        and K = 1e300 give inv(M) K = inf, which would end later in a LinAlgError or an
        integration that cannot take a step.
        """
        parts = [("matrices", "the state matrix", A), ("matrices", "the constant term", b0)]
        for term in terms:
            key = f"nonlinear.{term.name}"
            parts.append((key, "its direction", term.direction))
            parts.append((key, "its linear part", term.linear))
            for piece in term.abs_terms:
                parts.append((key, "an abs term", [piece.gain, piece.offset, *piece.row]))
        for source in sources:
            amplitude = getattr(source, "amplitude", 1.0)  # a sinusoid's; other inputs: 1
            with np.errstate(over="ignore", invalid="ignore"):
                scaled = np.asarray(source.direction, dtype=float) * amplitude
            parts.append((f"forcing.{source.name}", "its direction times amplitude", scaled))
        for key, what, values in parts:
            if not np.all(np.isfinite(np.asarray(values, dtype=float))):
                raise self._fail(
                    key,
                    f"{what} is not finite with coefficient set {set_name!r} (a product of "
                    "coefficients overflows, e.g. inv(M) K with a tiny mass): rescale the units",
                )

    def _initial(self, x0, value) -> np.ndarray:
        n = self.n
        if x0 is None or isinstance(x0, Mapping):
            out = np.zeros(n)
            for index, item in self.spec.initial.items():
                out[index] = value(item)
        if x0 is None:
            return out
        if isinstance(x0, Mapping):
            # named states override the file's initial values; the others keep them
            for name, entry in x0.items():
                if name not in self.states:
                    raise self._fail(
                        f"initial.{name}", f"unknown state (states: {', '.join(self.states)})"
                    )
                out[self.states.index(name)] = float(entry)
            return out
        out = np.asarray(x0, dtype=float).reshape(-1)
        if out.shape != (n,):
            raise self._fail("initial", f"x0 needs {n} values ({', '.join(self.states)})")
        return out.copy()


def _inputs(group: ForcingSpec, direction: np.ndarray, value, fail) -> list:
    """The System inputs of one forcing group (a sum of sines gives one Sinusoid each)."""
    unit, name = group.unit, group.name
    if group.kind == "sine":
        return [Sinusoid(direction, value(group.amplitude), value(group.frequency),
                         value(group.phase), unit, name)]  # fmt: skip
    if group.kind == "sines":
        return [
            Sinusoid(direction, value(a), value(f), value(p), unit, f"{name}{i}")
            for i, (a, f, p) in enumerate(group.components, start=1)
        ]
    amplitude = value(group.amplitude)
    if group.kind == "bump":
        duration = value(group.duration)
        if not duration > 0:
            raise fail(f"{group.key}.duration", f"must be positive, got {duration:g}")
        return [Bump(direction, amplitude, value(group.start), duration, group.shape, unit, name)]
    if group.kind == "step":
        start, rise = value(group.start), value(group.rise)
        if not rise >= 0:
            raise fail(f"{group.key}.rise", f"must be 0 or positive, got {rise:g}")
        times, values = [start, start + rise], [0.0, amplitude]
    else:
        points = np.array(group.points, dtype=float)
        times, values = points[:, 0], amplitude * points[:, 1]
        if group.speed is not None:
            speed = value(group.speed)
            if not speed > 0:
                raise fail(f"{group.key}.speed", f"must be positive, got {speed:g}")
            times = times / speed
    times, values = np.asarray(times, dtype=float), np.asarray(values, dtype=float)
    return [PiecewiseLinearInput(direction, times, values, unit, name, group.kind)]
