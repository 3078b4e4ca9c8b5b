"""Simulation results: time points plus named signals, as any engine produced them.

Our MNA engine and the ngspice runner both return :class:`Waveforms`, so comparisons never care
which engine ran. Signal names follow SPICE: ``v(node)`` for node voltages (lower case),
``i(vname)`` for source branch currents (lower case).
"""

from __future__ import annotations

import io
import os
from dataclasses import dataclass, field

import numpy as np

from circuitsim.atomic import write_atomic
from circuitsim.inputfile import RAW_FILE_BYTES, read_text
from circuitsim.netlist.names import fold


@dataclass
class Waveforms:
    """Time points and signals.

    Attributes
    ----------
    time : ndarray, shape (m,)
        Seconds, strictly increasing (for an operating point: one point at 0); for an
        ``.ac`` sweep the frequencies, Hz (``axis == "frequency"``).
    signals : dict of str to ndarray, shape (m,)
        Volts for ``v(...)``, amperes for ``i(...)``, in insertion order.
    engine : str
        Who produced them (``"builtin"``, ``"ngspice"``).
    stats : dict
        Engine statistics (accepted/rejected steps, Newton iterations, wall time s ...).
    axis : str
        What ``time`` holds: ``"time"`` (s) or ``"frequency"`` (Hz); the CSV's first column.
    """

    time: np.ndarray
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    engine: str = ""
    stats: dict = field(default_factory=dict)
    axis: str = "time"

    def __getitem__(self, name: str) -> np.ndarray:
        """The signal called ``name`` (case-insensitive; ``"out"`` means ``v(out)``)."""
        key = fold(name)
        if key in self.signals:
            return self.signals[key]
        if f"v({key})" in self.signals:
            return self.signals[f"v({key})"]
        raise KeyError(f"no signal {name!r}; have {', '.join(self.signals)}")

    def __contains__(self, name: str) -> bool:
        key = fold(name)
        return key in self.signals or f"v({key})" in self.signals

    @property
    def names(self) -> list[str]:
        """Signal names in order."""
        return list(self.signals)

    def at(self, times: np.ndarray, names: list[str] | None = None) -> Waveforms:
        """Linear interpolation onto ``times`` (s); outside the run the end values are held."""
        times = np.asarray(times, dtype=float)
        chosen = names if names is not None else self.names
        return Waveforms(
            time=times,
            signals={fold(n): np.interp(times, self.time, self[n]) for n in chosen},
            engine=self.engine,
            stats=dict(self.stats),
            axis=self.axis,
        )

    def select(self, names: list[str]) -> Waveforms:
        """Only the named signals (on the same time points)."""
        return Waveforms(
            time=self.time,
            signals={self._key(n): self[n] for n in names},
            engine=self.engine,
            stats=dict(self.stats),
            axis=self.axis,
        )

    def _key(self, name: str) -> str:
        key = fold(name)
        return key if key in self.signals else f"v({key})"

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write ``time,<signal>,...`` (``frequency,...`` for an ``.ac`` sweep) with a header
        row, atomically; every value with 17 significant digits, correctly rounded (it reads
        back exactly: float_text.py)."""
        columns = [self.time, *self.signals.values()]
        header = ",".join([self.axis, *self.signals])
        try:
            from circuitsim.solver.float_text import column_lines
        except ImportError:  # no numba: numpy's writer (the same values, ~6x slower)

            def column_lines(columns):
                text = io.StringIO()
                np.savetxt(text, np.column_stack(columns), delimiter=",", fmt="%.17g")
                yield text.getvalue().encode()

        def write(handle) -> None:
            handle.write(header.encode() + b"\n")
            for lines in column_lines(columns):
                handle.write(lines)

        write_atomic(path, write, binary=True)

    def to_npz(self, path: str | os.PathLike) -> None:
        """Write an ``.npz`` with ``time`` and one array per signal, atomically."""

        def write(handle) -> None:
            np.savez(handle, time=self.time, **self.signals)

        write_atomic(path, write, binary=True)

    @classmethod
    def from_csv(cls, path: str | os.PathLike, engine: str = "") -> Waveforms:
        """Read a file written by :meth:`to_csv` (at most
        :data:`~circuitsim.inputfile.RAW_FILE_BYTES`, like a raw file of results)."""
        text = read_text(path, RAW_FILE_BYTES, "a results file")
        header = text.partition("\n")[0].strip().split(",")
        data = np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, ndmin=2)
        return cls(
            time=data[:, 0],
            signals={name: data[:, i + 1] for i, name in enumerate(header[1:])},
            engine=engine,
            axis="frequency" if header[0] == "frequency" else "time",
        )
