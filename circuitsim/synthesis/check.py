"""Proof of the mapping: read a generated netlist back and recompute the model it realizes.

Nothing of the generator's memory is used: the circuit (or the file, parsed again) is walked
from the scale map's state nodes. For each state the op-amp driving its node is the inverter
(feedback Rf, input Rin from the integrator output), the op-amp driving that is the integrator
(capacitor C), and every resistor R into the integrator's summing junction contributes

    dx_i/dt += (Rf/Rin) / (K G_i C) * v_far / R,

with v_far recognized as a state node (+-G_j x_j), a SIN or DC source, or - through a switch -
a piecewise-linear signal, itself recomputed from its summers and from the precision |x| and
dead-zone blocks of :mod:`circuitsim.synthesis.nonlinear` (taken as their ideal transfer, after
checking their resistor ratios are the ideal ones). The recomputed A, forcing gains, constants
and nonlinear terms are compared with the model's, entry by entry, within the rounding error
the bill of materials reports for the resistors involved. How the circuit is read (nodes,
series pairs, sources, switches, the signals of the nonlinear blocks):
:mod:`circuitsim.synthesis.readback`; here, the model it realizes and the comparison.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from circuitsim.mechanics.system import Sinusoid, System
from circuitsim.netlist.circuit import Capacitor, Circuit, Pwl, Sin, Switch
from circuitsim.synthesis.blocks import BomEntry
from circuitsim.synthesis.bom import load_bom
from circuitsim.synthesis.errors import SynthesisError
from circuitsim.synthesis.readback import Affine, CircuitReader
from circuitsim.synthesis.report import Entry, MappingReport  # noqa: F401 - re-exported
from circuitsim.synthesis.scalemap import ScaleMap
from circuitsim.synthesis.stability import critical_speed

# A PWL source may depart from a smooth input by its sampling error (synthesis/inputs.py's
# SAMPLING_ERROR of the peak) and a little more.
SHAPE_TOLERANCE = 2e-4


def check_mapping(
    circuit_or_path: Circuit | str | os.PathLike,
    scale_map: ScaleMap | str | os.PathLike,
    system: System,
    bom: list[BomEntry] | str | os.PathLike | None = None,
    tolerance: float = 1e-9,
) -> MappingReport:
    """Recompute the model a netlist realizes and compare it with ``system``.

    Parameters
    ----------
    circuit_or_path : Circuit or path
        A path is parsed with the netlist reader (the honest check: what is in the file).
    scale_map : ScaleMap or path
        The scale file written beside the netlist.
    system : System
        The model the netlist should realize.
    bom : list of BomEntry or path, optional
        The bill of materials; each coefficient may be off by the sum of the reported
        |errors| of the resistors that set it. Without it every part must be exact.
    tolerance : float
        Added to every allowed relative error (float noise).

    Returns
    -------
    MappingReport
    """
    if not isinstance(circuit_or_path, Circuit):
        from circuitsim.netlist.reader import read_netlist

        circuit = read_netlist(circuit_or_path)
    else:
        circuit = circuit_or_path
    if not isinstance(scale_map, ScaleMap):
        scale_map = ScaleMap.load(scale_map)
    if bom is not None and not isinstance(bom, list):
        bom = load_bom(bom)
    errors = {e.part.lower(): abs(e.error) for e in (bom or []) if not math.isnan(e.error)}
    # the series the coefficient resistors were rounded to, named in advice: only parts whose
    # rounding moved a coefficient (fixed 10 kOhm parts are labelled E24 by membership)
    rounded = sorted(
        {e.series for e in (bom or []) if e.unit == "ohm" and e.series != "exact"
         and abs(e.error) > 1e-9}
    )  # fmt: skip
    return _Checker(circuit, scale_map, system, errors, tolerance, "/".join(rounded)).run()


class _Checker(CircuitReader):
    """The model a circuit realizes, recomputed from its elements (states, forcing,
    constants, piecewise-linear paths), and compared with ``system``."""

    def __init__(self, circuit, scale_map, system, errors, tolerance, series="") -> None:
        super().__init__(circuit, system.n)
        self.sm = scale_map
        self.sys = system
        self.errors = errors
        self.series = series  # "E96", "E24" ...; "" without a BOM or with exact values only
        self.tol = tolerance
        self.parts_ij: dict[tuple[int, int], tuple[str, ...]] = {}
        self.forcing: list[tuple] = []  # (state index, gain, model Hz, phase rad, part)
        self.inputs: list[tuple] = []  # (state index, gain, Pwl, time scale, part)
        self.constants: list[tuple] = []  # (state index, value, part)
        self.paths: list[tuple] = []  # (state index, Affine, t_on, switch name)

    def allowed(self, parts) -> float:
        # a series pair is named "R33A+R33B"; the bill of materials gives its error on R33A
        names = [q for p in parts for q in p.lower().split("+")]
        return sum(self.errors.get(q, 0.0) for q in names) + self.tol

    # --- states -------------------------------------------------------------------------

    def run(self) -> MappingReport:
        n, sysm = self.n, self.sys
        A_real = np.zeros((n, n))
        report = MappingReport(np.asarray(sysm.A, dtype=float), A_real)
        K = self.sm.time_scale
        try:
            missing = [s for s in sysm.states if s not in self.sm.states]
            if missing:
                raise SynthesisError(f"scale map lacks state(s) {', '.join(missing)}")
            integrators = {}
            for i, state in enumerate(sysm.states):
                scale = self.sm.states[state]
                plus = scale.node.lower()
                _, inv = self.opamp_inputs(plus)
                rs = self.resistors_at(inv)
                fb = [r for r in rs if self.far(r, inv) == plus]
                ins = [r for r in rs if self.far(r, inv) != plus]
                if len(fb) != 1 or len(ins) != 1:
                    raise SynthesisError(f"state {state}: node {plus} is not driven by an inverter")
                minus = self.far(ins[0], inv)
                ratio = float(fb[0].resistance) / float(ins[0].resistance)
                e = np.zeros(n)
                e[i] = scale.volts_per_unit
                self.state_expr[plus] = Affine(e.copy())
                self.state_expr[minus] = Affine(-e / ratio)
                integrators[state] = (i, minus, ratio, scale.volts_per_unit)
            for state, (i, minus, ratio, G) in integrators.items():
                self.integrator(state, i, minus, ratio, G, K, A_real, report)
        except SynthesisError as exc:
            report.problems.append(str(exc))
            return report
        for i in range(n):
            for j in range(n):
                if sysm.A[i, j] == 0 and A_real[i, j] == 0:
                    continue
                parts = self.parts_ij.get((i, j), ())
                report.entries.append(
                    Entry(
                        f"A[{sysm.states[i]}, {sysm.states[j]}]",
                        float(sysm.A[i, j]),
                        float(A_real[i, j]),
                        self.allowed(parts),
                        parts,
                    )
                )
        self.compare_forcing(report)
        self.compare_nonlinear(report)
        report.problems += self.problems
        report.problems += [
            f"{e.what}: realized {e.realized:.10g}, model {e.model:.10g} "
            f"(error {e.error:.3g}, allowed {e.allowed:.3g}; {', '.join(e.parts)})"
            for e in report.entries
            if not e.ok
        ]
        self.stability(report)
        return report

    def integrator(self, state, i, minus, ratio, G, K, A_real, report) -> None:
        _, junction = self.opamp_inputs(minus)
        caps = [
            e
            for e in self.by_node.get(junction, [])
            if isinstance(e, Capacitor) and self.far(e, junction) == minus
        ]
        if len(caps) != 1:
            raise SynthesisError(f"state {state}: no single integrator capacitor at {junction}")
        factor = ratio / (K * G * float(caps[0].capacitance))
        for r in self.resistors_at(junction):
            node, ohms, names = self.through(r, junction)
            gain = factor / ohms
            part = "+".join(names)  # R33A+R33B for a series pair
            if node in self.state_expr:
                expr = self.state_expr[node]
                A_real[i] += gain * expr.vec
                for j in np.flatnonzero(expr.vec):
                    self.parts_ij[(i, int(j))] = self.parts_ij.get((i, int(j)), ()) + names
                continue
            source = self.source_at(node)
            if source is not None:
                if isinstance(source.waveform, Sin):
                    w = source.waveform
                    self.forcing.append(
                        (i, gain * float(w.amplitude), float(w.frequency) / K,
                         math.radians(float(w.phase)), part)
                    )  # fmt: skip
                elif isinstance(source.waveform, Pwl):
                    self.inputs.append((i, gain, source.waveform, K, part))
                elif source.waveform is None:
                    self.constants.append((i, gain * float(source.dc), part))
                else:
                    self.problems.append(f"{part}: source {source.name} has an unknown waveform")
                continue
            switches = [e for e in self.by_node.get(node, []) if isinstance(e, Switch)]
            if len(switches) == 1:
                sw = switches[0]
                signal = self.far(sw, node)
                model = self.c.models.get(sw.model.lower())
                ron = float(model.params.get("ron", 1.0)) if model else 1.0
                total = ohms + ron
                expr = self.signal(signal).scaled(factor / total, names)
                self.paths.append((i, expr, self.switch_time(sw, K), sw.name))
                continue
            self.problems.append(f"{part}: input node {node!r} of {state} is not recognized")

    # --- comparisons --------------------------------------------------------------------

    def compare_forcing(self, report: MappingReport) -> None:
        realized = list(self.forcing)
        for k, force in enumerate(self.sys.forcing, start=1):
            if not isinstance(force, Sinusoid):
                self.compare_input(report, k, force)
                continue
            for i in np.flatnonzero(force.direction):
                model = float(force.direction[i]) * force.amplitude
                match = [
                    f for f in realized
                    if f[0] == i and math.isclose(f[2], force.frequency, rel_tol=1e-9)
                ]  # fmt: skip
                if not match:
                    if model != 0.0:  # a zero forcing (the free response) needs no source
                        self.problems.append(
                            f"forcing {k} into {self.sys.states[i]}: not in the netlist"
                        )
                    continue
                f = match[0]
                realized.remove(f)
                what = f"forcing {k} -> {self.sys.states[i]}"
                report.entries.append(
                    Entry(f"{what} gain", model, f[1], self.allowed((f[4],)), (f[4],))
                )
                report.entries.append(
                    Entry(f"{what} frequency", force.frequency, f[2], self.tol, (f[4],))
                )
                if not math.isclose(math.sin(f[3] - force.phase), 0, abs_tol=1e-9):
                    self.problems.append(f"{what}: phase {f[3]} rad, model {force.phase} rad")
        for f in realized:
            self.problems.append(f"{f[4]}: a sine input the model does not have")
        for f in self.inputs:
            self.problems.append(f"{f[4]}: a PWL input the model does not have")
        b_real = np.zeros(self.n)
        parts: dict[int, tuple] = {}
        for i, value, part in self.constants:
            b_real[i] += value
            parts[i] = parts.get(i, ()) + (part,)
        for i in range(self.n):
            if self.sys.b0[i] != 0 or b_real[i] != 0:
                report.entries.append(
                    Entry(f"b0[{self.sys.states[i]}]", float(self.sys.b0[i]), b_real[i],
                          self.allowed(parts.get(i, ())), parts.get(i, ()))
                )  # fmt: skip

    def compare_input(self, report: MappingReport, k: int, force) -> None:
        """A PWL-realized input: its gain (peak into each state) and its shape.

        The shape is compared at the midpoints of the PWL's segments (where a sampled bump's
        interpolation error is largest), except the short ramps written for the input's jumps.
        """
        for i in np.flatnonzero(force.direction):
            match = [f for f in self.inputs if f[0] == i]
            what = f"forcing {k} -> {self.sys.states[i]}"
            if not match:
                self.problems.append(f"{what}: not in the netlist")
                continue
            f = match[0]
            self.inputs.remove(f)
            _, gain, pwl, K, part = f
            times = np.array([float(t) for t, _ in pwl.points]) * K
            volts = np.array([float(v) for _, v in pwl.points])
            jumps = getattr(force, "times", np.empty(0))
            jumps = jumps[1:][np.diff(jumps) == 0]
            # the gain at the input's largest point in the run (a point of the PWL), not the
            # end of a ramp written for a jump if there is another: the input has moved on
            # over the ramp (1.3e-6 of its value for a 0.63 us ramp on a 0.5 s segment)
            after_ramp = np.zeros(times.size, dtype=bool)
            for at in jumps:
                after_ramp[1:] |= np.isclose(times[:-1], at, rtol=1e-9, atol=0.0)
            size = np.where(after_ramp, 0.0, np.abs(volts))
            p = int(np.argmax(size if size.any() else np.abs(volts)))
            model = float(force.direction[i]) * float(force.value(times[p]))
            report.entries.append(
                Entry(f"{what} gain", model, gain * volts[p], self.allowed((part,)), (part,))
            )
            middle = 0.5 * (times[:-1] + times[1:])
            # the ramps written for the input's jumps are no part of the comparison
            ramp = np.zeros(middle.size, dtype=bool)
            for at in jumps:
                ramp |= (times[:-1] <= at) & (at <= times[1:])
            middle = middle[~ramp]
            if middle.size == 0:
                continue
            realized = gain * np.interp(middle, times, volts)
            wanted = float(force.direction[i]) * np.asarray(force.value(middle))
            worst = float(np.max(np.abs(realized - wanted))) / max(abs(model), 1e-300)
            if worst > SHAPE_TOLERANCE + self.allowed((part,)):
                self.problems.append(
                    f"{what} ({part}): the PWL source departs from the input by {worst:.2e} of "
                    f"its peak"
                )

    def compare_nonlinear(self, report: MappingReport) -> None:
        n = self.n
        lin_model, lin_real = np.zeros((n, n)), np.zeros((n, n))
        const_model, const_real = np.zeros(n), np.zeros(n)
        pieces_model: list[tuple[int, float, np.ndarray, float]] = []
        pieces_real: list[tuple[int, float, np.ndarray, float, tuple]] = []
        parts_row: dict[int, tuple] = {}
        t_on_model = {}
        for term in self.sys.nonlinear:
            d = np.asarray(term.direction, dtype=float)
            lin_model += np.outer(d, term.linear)
            const_model += d * term.constant
            for i in np.flatnonzero(d):
                t_on_model[int(i)] = term.t_on
                for piece in term.abs_terms:
                    if piece.gain == 0:  # adds nothing; the translator builds no block for it
                        continue
                    pieces_model.append(
                        (int(i), d[i] * piece.gain, np.asarray(piece.row, float), piece.offset)
                    )
        for i, expr, t_on, switch in self.paths:
            lin_real[i] += expr.vec
            const_real[i] += expr.const
            parts_row[i] = parts_row.get(i, ()) + expr.parts
            for g, row, off in expr.pieces:
                pieces_real.append((i, g, row, off, expr.parts))
            want = t_on_model.get(i, "absent")
            if want == "absent":
                self.problems.append(f"switch {switch}: the model has no nonlinear term there")
            elif want is not None and t_on is not None and math.isinf(want) and math.isinf(t_on):
                continue  # open throughout, as the model says (the paper's S1 open)
            elif (want or 0.0) > 0 or (t_on or 0.0) > 0:
                report.entries.append(
                    Entry(f"{switch} closing time", float(want or 0.0), float(t_on or 0.0),
                          1e-3, (switch,))
                )  # fmt: skip
        states = self.sys.states
        for i in range(n):
            allowed = self.allowed(parts_row.get(i, ()))
            for j in range(n):
                if lin_model[i, j] or lin_real[i, j]:
                    report.entries.append(
                        Entry(f"nonlinear linear part [{states[i]}, {states[j]}]",
                              lin_model[i, j], lin_real[i, j], allowed, parts_row.get(i, ()))
                    )  # fmt: skip
            if const_model[i] or const_real[i]:
                report.entries.append(
                    Entry(f"nonlinear constant [{states[i]}]", const_model[i], const_real[i],
                          allowed, parts_row.get(i, ()))
                )  # fmt: skip
        # |x| pieces: normalize each row by its entry at the model row's largest entry (the
        # pivot), so g |row . x + off| = g |lam| |row/lam . x + off/lam| compares like for like
        real = list(pieces_real)
        for i, g, row, off in pieces_model:
            pivot = int(np.argmax(np.abs(row)))
            lam = row[pivot]
            g, row, off = g * abs(lam), row / lam, off / lam
            what = f"|x| piece into {states[i]} at offset {off:.6g}"
            normalized = [
                (q, q[1] * abs(q[2][pivot]), q[2] / q[2][pivot], q[3] / q[2][pivot], q[4])
                for q in real
                if q[0] == i and q[2][pivot] != 0
            ]
            if not normalized:
                self.problems.append(f"{what}: not in the netlist")
                continue
            # the nearest realized kink into the same state (rounded argument summers move it)
            scale = max(abs(off), 1e-300)
            q, gain_r, row_r, off_r, parts = min(
                normalized, key=lambda p: np.sum(np.abs(p[2] - row)) + abs(p[3] - off) / scale
            )
            real.remove(q)
            allowed = self.allowed(parts)
            report.entries.append(Entry(f"{what} gain", g, gain_r, allowed, parts))
            report.entries.append(Entry(f"{what} offset", off, off_r, allowed, parts))
            for j in np.flatnonzero(row):
                if j != pivot:
                    report.entries.append(
                        Entry(f"{what} row [{states[j]}]", row[j], row_r[j], allowed, parts)
                    )
        for q in real:
            if q[1] != 0:
                self.problems.append(
                    f"an |x| piece into {states[q[0]]} (offset {q[3]:.6g}) the model lacks"
                )

    def stability(self, report: MappingReport) -> None:
        report.eigenvalues_model = np.linalg.eigvals(report.A_model)
        report.eigenvalues_realized = np.linalg.eigvals(report.A_realized)
        hint = (self.sys.circuit_hints or {}).get("speed")
        if not isinstance(hint, dict):
            return
        name = hint.get("parameter", "V")
        if name not in self.sys.parameters:
            return
        index = {s: i for i, s in enumerate(self.sys.states)}
        entries = [(index[a], index[b]) for a, b in hint.get("entries", [])]
        speed = float(self.sys.parameters[name])
        report.speed = speed
        report.critical_speed_model = critical_speed(report.A_model, entries, speed)
        report.critical_speed_realized = critical_speed(report.A_realized, entries, speed)
        vm, vr = report.critical_speed_model, report.critical_speed_realized
        if vm is not None and vr is not None and (vm - speed) * (vr - speed) < 0:
            report.warnings.append(self.stability_warning(report, speed, vm, vr))

    def stability_warning(self, report: MappingReport, speed: float, vm: float, vr: float) -> str:
        """The warning for a simulated speed between the model's and the circuit's critical speed.

        Parameters
        ----------
        report : MappingReport
            With the eigenvalues of the model's and the realized linear part at ``speed``.
        speed : float
            The simulated speed.
        vm, vr : float
            The model's and the realized circuit's critical speeds.

        Returns
        -------
        str
            Which of the two is unstable at ``speed``, and what realizes the model's stability,
            spelled for the command line and for the Python API alike (``circuitsim
            generate``/``compare`` and :func:`~circuitsim.synthesis.generate.generate` users
            read it); the finer E96 series is suggested only to users of a coarser one.
        """
        circuit = f"the circuit with {self.series} resistors" if self.series else "the circuit"
        model_grows = float(np.max(report.eigenvalues_model.real)) >= 0
        circuit_grows = float(np.max(report.eigenvalues_realized.real)) >= 0
        if model_grows == circuit_grows:  # a crossing within float noise of the speed
            verdict = f"the stability of {circuit} differs from the model's"
        elif circuit_grows:
            verdict = f"the model is stable but {circuit} is not"
        else:
            verdict = f"the model is unstable but {circuit} is stable"
        advice = (
            "exact resistor values (--series exact, or SynthesisOptions(series='exact')) "
            "realize the model's critical speed"
        )
        if self.series and self.series != "E96":
            advice += "; E96 (--series E96) rounds less"
        return (
            f"rounding moves the critical speed across the simulated speed {speed:g}: "
            f"model {vm:.4f}, realized circuit {vr:.4f} - at {speed:g} {verdict}; {advice}"
        )


def check_files(netlist: str | os.PathLike, system: System) -> MappingReport:
    """Check ``FILE.cir`` with its ``FILE.scale.json`` and ``FILE.bom.csv`` beside it."""
    path = Path(netlist)
    stem = path.with_suffix("")
    bom = Path(f"{stem}.bom.csv")
    return check_mapping(
        path, Path(f"{stem}.scale.json"), system, bom=bom if bom.exists() else None
    )
