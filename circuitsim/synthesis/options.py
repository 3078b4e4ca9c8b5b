"""What the translator is asked to do: one frozen options object, validated once."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from circuitsim.synthesis.errors import SynthesisError

#: Peak output swing (V) beyond which a signal is reported as clipping, per op-amp kind.
#: A library op-amp ("lib") is assumed to swing as the TL074 on the same +/-15 V supplies.
SWING_LIMIT = {"ideal": math.inf, "tl074": 13.0, "lib": 13.0}


@dataclass(frozen=True)
class SynthesisOptions:
    """Translator options.

    Attributes
    ----------
    opamp : str
        ``"ideal"`` (high-gain controlled source), ``"tl074"`` (macromodel, +/-15 V supplies)
        or ``"lib"``: the 5-pin subcircuit ``opamp_subckt`` of the library file ``opamp_lib``
        (pins in+, in-, V+, V-, out; see :mod:`circuitsim.synthesis.opamp_library`).
    opamp_lib, opamp_subckt : str or None
        The library file and subcircuit name of ``opamp="lib"`` (both given then, else None).
    nonlinear : str
        ``"abs"``: each piecewise-linear term literally from precision |x| blocks (the paper's
        form); ``"deadzone"``: one dead-zone block where the term has that shape.
    scaling : str
        ``"auto"``: volts per unit from the direct solution's peaks (or ``ranges``) to ``swing``;
        ``"unity"``: 1 V per SI unit for every state (the paper's mapping).
    swing : float
        Target peak voltage of every state signal in ``auto`` scaling (V).
    time_scale : float or None
        K: one model second takes 1/K circuit seconds (1 = real time); None (default): the
        model file's ``[circuit] time_scale``, else 1.
    series : str
        Resistor rounding: ``"E96"``, ``"E24"`` or ``"exact"``.
    pair_tolerance : float
        Largest relative error of a coefficient-setting resistor realized by one standard
        value; beyond it the resistor is two standard values in series (``R33A`` + ``R33B``).
        ``inf``: never a pair (every resistor one rounded value).
    t_stop : float or None
        Model seconds to simulate (and to take peaks over); None: the model's hint or 5 s.
    ranges : dict of str to float
        User-given peak magnitude per state (SI units), overriding the direct solution's peak.
    r_min, r_max : float
        Preferred resistor range (ohms); values outside it are warned about.
    r_unit : float
        Resistor of the unity-gain stages (inverters, summer feedback), ohms.
    switch_ron, switch_roff : float
        The switch model's on and off resistance (ohms); Ron is compensated in the series R.
    points_per_period : int
        ``.tran`` maximum step = shortest period of the run / this.
    scaling_wall_time : float
        Most wall time (s) of the direct solution that sets the scales and predicts the
        peaks; past it a SynthesisError says where it stopped.
    opamp_offset, opamp_bias : dict of str to float
        Input offset voltage (V) and input bias current (A) of the ``tl074`` sections, by
        section name (``"U1A"``) or ``"*"`` for every section not named; empty (default): none
        (:func:`~circuitsim.synthesis.offsets.apply_opamp_errors`).
    """

    opamp: str = "ideal"
    opamp_lib: str | None = None
    opamp_subckt: str | None = None
    nonlinear: str = "abs"
    scaling: str = "auto"
    swing: float = 5.0
    time_scale: float | None = None
    series: str = "E96"
    pair_tolerance: float = 1e-3
    t_stop: float | None = None
    ranges: dict[str, float] = field(default_factory=dict)
    r_min: float = 1e3
    r_max: float = 1e6
    r_unit: float = 10e3
    switch_ron: float = 1.0
    switch_roff: float = 1e12
    points_per_period: int = 200
    scaling_wall_time: float = 60.0
    opamp_offset: dict[str, float] = field(default_factory=dict)
    opamp_bias: dict[str, float] = field(default_factory=dict)

    def validated(self) -> SynthesisOptions:
        """Self, after checking every field; SynthesisError naming the bad option."""
        choices = {
            "opamp": ("ideal", "tl074", "lib"),
            "nonlinear": ("abs", "deadzone"),
            "scaling": ("auto", "unity"),
        }
        for key, allowed in choices.items():
            if getattr(self, key) not in allowed:
                raise SynthesisError(
                    f"option {key}={getattr(self, key)!r}: choose one of {', '.join(allowed)}"
                )
        library = (self.opamp_lib is not None, self.opamp_subckt is not None)
        if (self.opamp == "lib") != all(library) or any(library) != all(library):
            raise SynthesisError(
                "option opamp='lib' goes with both opamp_lib (a library file) and opamp_subckt "
                "(its op-amp subcircuit), and they with it"
            )
        if self.series.lower() not in ("e96", "e24", "exact"):
            raise SynthesisError(f"option series={self.series!r}: choose E96, E24 or exact")
        positive = ("swing", "time_scale", "r_min", "r_max", "r_unit", "switch_ron",
                    "scaling_wall_time")  # fmt: skip
        for key in positive:
            value = getattr(self, key)
            if key == "time_scale" and value is None:  # the model's, else 1
                continue
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise SynthesisError(f"option {key}={value!r}: must be a positive number")
        if not (isinstance(self.pair_tolerance, int | float) and self.pair_tolerance >= 0):
            raise SynthesisError(
                f"option pair_tolerance={self.pair_tolerance!r}: must be a number >= 0 (inf: "
                "no series pairs)"
            )
        if self.t_stop is not None and not (math.isfinite(self.t_stop) and self.t_stop > 0):
            raise SynthesisError(f"option t_stop={self.t_stop!r}: must be a positive number")
        if self.r_min >= self.r_max:
            raise SynthesisError("option r_min must be below r_max")
        self._check_opamp_errors()
        for name, peak in self.ranges.items():
            if not (math.isfinite(peak) and peak > 0):
                raise SynthesisError(f"option ranges[{name!r}]={peak!r}: must be positive")
        return self

    def _check_opamp_errors(self) -> None:
        from circuitsim.synthesis.offsets import check_section_values

        check_section_values(self.opamp_offset, "offset", "volts")
        check_section_values(self.opamp_bias, "bias", "amperes")
        given = [v for v in (*self.opamp_offset.values(), *self.opamp_bias.values()) if v != 0]
        if given and self.opamp != "tl074":
            raise SynthesisError(
                f"op-amp offsets and bias currents need opamp='tl074' (--opamp tl074); the "
                f"{self.opamp} op-amp has no input errors"
            )

    @property
    def series_key(self) -> str:
        """``"E96"``, ``"E24"`` or ``"exact"``."""
        return "exact" if self.series.lower() == "exact" else self.series.upper()
