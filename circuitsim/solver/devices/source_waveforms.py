"""Values of independent sources over time: DC, SIN, PULSE, PWL, evaluated per kind in bulk.

SPICE defaults that depend on the analysis follow ngspice (vsrcload.c semantics): a PULSE rise
or fall time of 0 means ``tstep``, its width and period default to ``tstop``; a SIN frequency of
0 means ``1/tstop``. For a stand-alone ``.op`` a source uses its DC value when one was given
(non-zero) and otherwise its waveform at t = 0; the operating point before ``.tran`` uses the
waveform at t = 0.

Kernel twin: source_kernel.py, one source's transient value, compiled (numba) for the compiled
loops (solver/compiled/), which read the sources as ``kernel_arrays`` describes them.
"""

from __future__ import annotations

import numpy as np

from circuitsim.netlist.circuit import Pulse, Pwl, Sin
from circuitsim.solver.devices.base import number
from circuitsim.solver.errors import CircuitInputError

MAX_BREAKPOINTS = 1_000_000


class SourceValues:
    """Time functions of m independent sources.

    Parameters
    ----------
    elements : list of VoltageSource or CurrentSource
        Each with ``dc`` and optional ``waveform``.
    """

    def __init__(self, elements):
        m = len(elements)
        self.dc = np.array([number(e.dc, e.name, "DC value") for e in elements])
        self.has_waveform = np.array([e.waveform is not None for e in elements], dtype=bool)
        self.sin_index = [i for i, e in enumerate(elements) if isinstance(e.waveform, Sin)]
        self.pulse_index = [i for i, e in enumerate(elements) if isinstance(e.waveform, Pulse)]
        self.pwl: list[tuple[int, np.ndarray, np.ndarray]] = []
        for i, e in enumerate(elements):
            if isinstance(e.waveform, Pwl):
                pts = [
                    (number(t, e.name, "PWL time"), number(v, e.name, "PWL value"))
                    for t, v in e.waveform.points
                ]
                if not pts:
                    raise CircuitInputError(f"{e.name}: PWL without points")
                t, v = np.array(pts).T
                if np.any(np.diff(t) < 0):
                    raise CircuitInputError(f"{e.name}: PWL times must not decrease")
                self.pwl.append((i, t, v))
        s = [elements[i] for i in self.sin_index]
        self.sin = {
            key: np.array([number(getattr(e.waveform, key), e.name, f"SIN {key}") for e in s])
            for key in ("offset", "amplitude", "frequency", "delay", "damping", "phase")
        }
        p = [elements[i] for i in self.pulse_index]
        self.pulse = {
            key: np.array([_pulse_value(e, key) for e in p])
            for key in ("initial", "pulsed", "delay", "rise", "fall", "width", "period")
        }
        self.size = m
        self.set_timing(1.0, 1.0)

    def set_timing(self, tstep: float, tstop: float) -> None:
        """Fill the analysis-dependent defaults (see module docstring)."""
        pu = self.pulse
        self.rise = np.where(pu["rise"] > 0, pu["rise"], tstep)
        self.fall = np.where(pu["fall"] > 0, pu["fall"], tstep)
        finite_w = np.isfinite(pu["width"]) & (pu["width"] > 0)
        self.width = np.where(finite_w, pu["width"], tstop)
        finite_p = np.isfinite(pu["period"]) & (pu["period"] > 0)
        self.period = np.where(finite_p, pu["period"], tstop)
        f = self.sin["frequency"]
        self.frequency = np.where(f != 0, f, 1.0 / tstop)
        self._omega = 2 * np.pi * self.frequency
        self._phase = np.deg2rad(self.sin["phase"])
        self._damped = bool(np.count_nonzero(self.sin["damping"]))
        self._delayed = bool(np.count_nonzero(self.sin["delay"]))

    def values(self, time: float, dc_op: bool = False) -> np.ndarray:
        """Source values at ``time`` (s), shape (m,); ``dc_op`` for a stand-alone ``.op``."""
        out = self.dc.copy()
        if self.sin_index:
            s = self.sin
            # (the delay and damping terms only where some source has them: this runs once
            # per time step)
            tau = np.maximum(time - s["delay"], 0.0) if self._delayed else time
            wave = s["amplitude"] * np.sin(self._omega * tau + self._phase)
            if self._damped:
                wave *= np.exp(-s["damping"] * tau)
            out[self.sin_index] = wave + s["offset"]
        if self.pulse_index:
            out[self.pulse_index] = self._pulse(time)
        for i, t, v in self.pwl:
            out[i] = np.interp(time, t, v)
        if dc_op:
            keep_dc = ~self.has_waveform | (self.dc != 0)
            out[keep_dc] = self.dc[keep_dc]
        return out

    def kernel_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
        """The sources as the compiled loops read them: kinds and parameter columns named in
        the kernel twin, source_kernel.py, whose source_value computes the values.

        Returns
        -------
        kind : ndarray of int, shape (m,)
            source_kernel.DC, SIN, PULSE or PWL.
        par : ndarray, shape (m, source_kernel.PARAM_COLUMNS)
            SIN: offset, amplitude, angular frequency (rad/s), delay (s), damping (1/s),
            phase (rad). PULSE: initial, pulsed, delay, rise, fall, width, period (s).
        dc : ndarray, shape (m,)
        pwl : list of ndarray, shape (2, k) each
            (times, values) of each source, empty for non-PWL sources.
        """
        from circuitsim.solver.devices import source_kernel as twin  # numba: compiled runs only

        m = self.size
        kind = np.full(m, twin.DC, dtype=np.int64)
        par = np.zeros((m, twin.PARAM_COLUMNS))
        s = self.sin
        for j, i in enumerate(self.sin_index):
            kind[i] = twin.SIN
            par[i, twin.OFFSET] = s["offset"][j]
            par[i, twin.AMPLITUDE] = s["amplitude"][j]
            par[i, twin.OMEGA] = self._omega[j]
            par[i, twin.SIN_DELAY] = s["delay"][j]
            par[i, twin.DAMPING] = s["damping"][j]
            par[i, twin.PHASE] = self._phase[j]
        pu = self.pulse
        for j, i in enumerate(self.pulse_index):
            kind[i] = twin.PULSE
            par[i, twin.INITIAL] = pu["initial"][j]
            par[i, twin.PULSED] = pu["pulsed"][j]
            par[i, twin.PULSE_DELAY] = pu["delay"][j]
            par[i, twin.RISE] = self.rise[j]
            par[i, twin.FALL] = self.fall[j]
            par[i, twin.WIDTH] = self.width[j]
            par[i, twin.PERIOD] = self.period[j]
        pwl = [np.zeros((2, 0)) for _ in range(m)]
        for i, t, v in self.pwl:
            kind[i] = twin.PWL
            pwl[i] = np.stack([t, v])
        return kind, par, self.dc.copy(), pwl

    def _pulse(self, time: float) -> np.ndarray:
        pu = self.pulse
        v1, v2 = pu["initial"], pu["pulsed"]
        tr, tf, pw, per = self.rise, self.fall, self.width, self.period
        tau = time - pu["delay"]
        tau = np.where(tau > per, tau - per * np.floor(tau / per), tau)
        rising = v1 + (v2 - v1) * tau / tr
        falling = v2 + (v1 - v2) * (tau - tr - pw) / tf
        return np.select(
            [(tau <= 0) | (tau >= tr + pw + tf), (tau >= tr) & (tau <= tr + pw), tau < tr],
            [v1, v2, rising],
            falling,
        )

    def breakpoints(self, tstop: float) -> np.ndarray:
        """Waveform corners in [0, tstop], seconds, unsorted."""
        out = []
        if self.sin_index:
            td = self.sin["delay"]
            out.append(td[(td > 0) & (td < tstop)])
        for k in range(len(self.pulse_index)):
            td, per = self.pulse["delay"][k], self.period[k]
            corners = np.array(
                [
                    0.0,
                    self.rise[k],
                    self.rise[k] + self.width[k],
                    self.rise[k] + self.width[k] + self.fall[k],
                ]
            )
            count = int(min(max(np.ceil((tstop - td) / per), 0) + 1, MAX_BREAKPOINTS))
            starts = td + per * np.arange(count)
            points = (starts[:, None] + corners[None, :]).ravel()
            out.append(points[(points >= 0) & (points <= tstop)])
        for _, t, _ in self.pwl:
            out.append(t[(t >= 0) & (t <= tstop)])
        return np.concatenate(out) if out else np.zeros(0)


def _pulse_value(element, key: str) -> float:
    raw = getattr(element.waveform, key)
    if raw is None:
        return np.inf
    value = number(raw, element.name, f"PULSE {key}")
    # ngspice 39 fails on a negative rise or fall time ("impossible error") and holds the
    # initial value for ever with a negative width; a negative delay shifts the pulse train
    # earlier, as there (and here)
    if key in ("rise", "fall", "width", "period") and value < 0:
        raise CircuitInputError(
            f"{element.name}: PULSE {key} {value:g} s is negative (a time span must be >= 0; "
            "0 means the default)"
        )
    return value
