"""Test benches for the part library and the measurements taken from them.

Each bench is SPICE text that ``.include``s the shipped ``parts.lib`` (so what is measured is
the file users get), runs on any engine given as ``run(text) -> Waveforms``, and each
measurement is taken from the simulated waveforms the way one would on a bench: no figure is
read from the model's own parameters. Shared by the tests and by ``report.py`` (docs/parts.md).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable

import numpy as np
import pytest

from circuitsim.netlist.circuit import Circuit, Pwl, Resistor, Sin, Transient, VoltageSource
from circuitsim.netlist.library import LIBRARY_PATH
from circuitsim.solver.waveforms import Waveforms
from circuitsim.synthesis.nonlinear import add_dead_zone, add_precision_abs
from circuitsim.synthesis.opamps import add_opamp

Run = Callable[[str], Waveforms]

requires_ngspice = pytest.mark.skipif(
    shutil.which("ngspice") is None,
    reason="ngspice is not installed (apt-get install -y ngspice; CI installs it)",
)

DESIGN = {
    "dc_gain": 200e3,  # V/V: 200 V/mV (TL07x datasheet typical)
    "unity_gain_hz": 3e6,  # Hz (datasheet typical unity-gain bandwidth)
    "slew_v_per_us": 13.0,  # V/us (datasheet typical, unity gain)
    "swing_pos_v": 13.5,  # V into 10 kOhm on +/-15 V (datasheet typical)
    "swing_neg_v": -13.5,
    "output_ohm": 100.0,  # open-loop output resistance, our choice (docs/parts.md)
    "input_ohm": 1e12,  # datasheet typical
}
"""Design figures of the TL074-like macromodel, from the datasheet, not from parts.lib."""

SUPPLIES = "VCC vcc 0 15\nVEE vee 0 -15\n"


def run_builtin(netlist: Circuit | str) -> Waveforms:
    """Our solver on a Circuit or on SPICE text (read by our reader), like ``run_ngspice``."""
    from circuitsim.netlist.reader import parse_netlist
    from circuitsim.solver import simulate

    circuit = netlist if isinstance(netlist, Circuit) else parse_netlist(netlist, "<bench>")
    return simulate(circuit)


def engines() -> dict[str, Run]:
    """Name -> run(netlist) for each engine: ngspice (when installed) and ours."""
    from circuitsim.interop.ngspice import run_ngspice

    found: dict[str, Run] = {}
    if shutil.which("ngspice") is not None:
        found["ngspice"] = run_ngspice
    found["builtin"] = run_builtin
    return found


def figures(run: Run) -> dict[str, float]:
    """Every figure of ``DESIGN`` measured with ``run`` (slew: the smaller direction)."""
    rising, falling = slew_rate(run)
    high, low = swing(run)
    return {
        "dc_gain": dc_gain(run),
        "unity_gain_hz": unity_gain_frequency(run),
        "slew_v_per_us": min(rising, falling),
        "swing_pos_v": high,
        "swing_neg_v": low,
        "output_ohm": output_resistance(run),
        "input_ohm": input_resistance(run),
    }


def deck(body: str, analysis: str, title: str = "part bench") -> str:
    """A complete netlist: title, the library include, ``body``, ``analysis``, ``.end``."""
    return f"{title}\n.include {LIBRARY_PATH}\n{body}{analysis}\n.end\n"


def open_loop_output(run: Run, vd: float, load: str = "") -> float:
    """v(out) of an open-loop TL074 with differential input ``vd`` (V); ``.op``."""
    body = SUPPLIES + f"VP p 0 {vd!r}\nXU p 0 vcc vee out TL074\n" + load
    return float(run(deck(body, ".op"))["v(out)"][0])


def dc_gain(run: Run, vd: float = 10e-6) -> float:
    """Open-loop DC gain, V/V, from the outputs at +vd and -vd (unloaded)."""
    return (open_loop_output(run, vd) - open_loop_output(run, -vd)) / (2 * vd)


def swing(run: Run, load_ohm: float = 10e3) -> tuple[float, float]:
    """Clipping levels (V) into ``load_ohm`` on +/-15 V: (positive, negative)."""
    load = f"RL out 0 {load_ohm!r}\n"
    return open_loop_output(run, 1.0, load), open_loop_output(run, -1.0, load)


def output_resistance(run: Run, test_amps: float = 1e-3) -> float:
    """Open-loop output resistance, ohms: inputs grounded, ``test_amps`` drawn from the output."""
    body = SUPPLIES + f"XU 0 0 vcc vee out TL074\nIT out 0 {test_amps!r}\n"
    return -float(run(deck(body, ".op"))["v(out)"][0]) / test_amps


def input_resistance(run: Run) -> float:
    """Differential input resistance, ohms: 1 V across the inputs, the current measured."""
    body = SUPPLIES + "VP p 0 1\nXU p 0 vcc vee out TL074\n"
    return 1.0 / abs(float(run(deck(body, ".op"))["i(vp)"][0]))


def follower_step(
    run: Run, low: float, high: float, tstop: float, tstep: float, load: str = ""
) -> Waveforms:
    """Unity-gain follower: the input steps from ``low`` to ``high`` (V) at 0.1 us, 1 ns edge."""
    body = (
        SUPPLIES
        + f"VIN in 0 PULSE({low!r} {high!r} 0.1u 1n 1n 1 2)\nXU in out vcc vee out TL074\n"
        + load
    )
    return run(deck(body, f".tran {tstep!r} {tstop!r} 0 {tstep!r}"))


def unity_gain_frequency(run: Run, step: float = 0.01) -> float:
    """Unity-gain frequency, Hz, from a small step of an unloaded follower.

    The follower's closed loop is a single pole at the unity-gain frequency f_u (times
    A0 / (1 + A0), a 5e-6 correction), so the error decays as exp(-2 pi f_u t); f_u comes from a
    straight-line fit of log(error) between 90 % and 10 % of the step.
    """
    waves = follower_step(run, 0.0, step, 1.5e-6, 2e-9)
    t, v = waves.time, waves["v(out)"]
    error = step - v
    window = (t > 0.1e-6) & (error < 0.9 * step) & (error > 0.1 * step)
    slope = np.polyfit(t[window], np.log(error[window]), 1)[0]
    return -slope / (2 * np.pi)


def slew_rate(run: Run) -> tuple[float, float]:
    """Slew rates, V/us, rising and falling, of a follower (10 kOhm load) stepping +/-5 V.

    Measured between 10 % and 90 % of the 10 V swing; with 0.69 V of linear input range
    the stage is current-limited over all of it.
    """
    rates = []
    for low, high in ((-5.0, 5.0), (5.0, -5.0)):
        waves = follower_step(run, low, high, 2e-6, 5e-9, "RL out 0 10k\n")
        t, v = waves.time, waves["v(out)"]
        a, b = low + 0.1 * (high - low), low + 0.9 * (high - low)
        ta, tb = _crossing(t, v, a), _crossing(t, v, b)
        rates.append(abs(b - a) / (tb - ta) / 1e6)
    return rates[0], rates[1]


def offset_output(run: Run, vos: float) -> float:
    """Output (V) of a grounded-input follower whose TL074 has ``vos`` volts of offset."""
    body = SUPPLIES + f"XU 0 out vcc vee out TL074 vos={vos!r}\n"
    return float(run(deck(body, ".op"))["v(out)"][0])


def _crossing(t: np.ndarray, v: np.ndarray, level: float) -> float:
    """First time (s) ``v`` passes ``level`` towards its final value, linearly interpolated."""
    beyond = v > level if v[-1] > level else v < level
    i = int(np.argmax(beyond))
    if i == 0:
        raise ValueError(f"the waveform never crosses {level} V")
    t0, t1, v0, v1 = t[i - 1], t[i], v[i - 1], v[i]
    return float(t0 + (level - v0) * (t1 - t0) / (v1 - v0))


# --- nonlinear blocks -----------------------------------------------------------------------

BLOCK_R = 10e3
"""Resistance the block benches use, ohms."""
FULL_SCALE = 10.0
"""The ramp benches sweep -FULL_SCALE .. +FULL_SCALE volts."""
ETA = 2.0
"""Dead-zone half-width of the block benches, volts (the abs form then sees up to 12 V,
inside the TL074 block's range, docs/parts.md)."""


def ramp_circuit(span: float = 10.0, duration: float = 10e-3, points: int = 1000) -> Circuit:
    """A circuit with a slow ramp from -span to +span (V) at node ``in`` (and its negative
    at ``nin``) and a ``.tran`` with at most ``duration / points`` between time points."""
    circuit = Circuit("block ramp bench")
    ramp = Pwl(((0.0, -span), (duration, span)))
    back = Pwl(((0.0, span), (duration, -span)))
    circuit.add(
        VoltageSource("VIN", "in", "0", waveform=ramp),
        VoltageSource("VNIN", "nin", "0", waveform=back),
    )
    step = duration / points
    circuit.analyses.append(Transient(step, duration, tmax=step))
    return circuit


def sine_circuit(
    amplitude: float, frequency: float, periods: float = 2.0, points: int = 4000
) -> Circuit:
    """A sine of ``amplitude`` (V) and ``frequency`` (Hz) at ``in``, ``points`` steps a period."""
    circuit = Circuit("block sine bench")
    circuit.add(VoltageSource("VIN", "in", "0", waveform=Sin(0.0, amplitude, frequency)))
    step = 1.0 / frequency / points
    circuit.analyses.append(Transient(step, periods / frequency, tmax=step))
    return circuit


def dead_zone(x: np.ndarray, eta: float) -> np.ndarray:
    """The dead zone: 0 inside +/-eta, slope 1 outside."""
    return np.sign(x) * np.maximum(np.abs(x) - eta, 0.0)


def glitch(
    run_circuit: Callable[[Circuit], Waveforms],
    kind: str,
    frequency: float,
    amplitude: float = 5.0,
    points: int = 4000,
) -> tuple[float, float, float]:
    """Zero-crossing glitch of the precision |x| block driven by a sine.

    Simulated for 1.5 periods; measured over the period from 0.5/f to 1.5/f, which holds one
    falling and one rising crossing (the start-up at t = 0 is not a glitch).

    Returns
    -------
    peak_error : float
        Largest |v(out) - |v(in)|| over that period, volts.
    width : float
        Time (s) in that period that the error exceeds 1 % of ``amplitude``.
    mean_ratio : float
        Time-average of |v(out) - |v(in)|| over that of |v(in)| (what an integrator fed by
        the block sees), dimensionless.
    """
    circuit = sine_circuit(amplitude, frequency, 1.5, points)
    add_precision_abs(circuit, "ABS1", "in", "out", BLOCK_R, kind)
    waves = run_circuit(circuit)
    second = waves.time >= 0.5 / frequency
    t = waves.time[second]
    error = np.abs(waves["out"] - np.abs(waves["in"]))[second]
    dt = np.diff(t)
    bad = error[1:] > 0.01 * amplitude
    width = float(np.sum(dt[bad]))
    mean_ratio = _integral(t, error) / _integral(t, np.abs(waves["in"][second]))
    return float(error.max()), width, mean_ratio


def _integral(t: np.ndarray, y: np.ndarray) -> float:
    """Trapezoid integral of samples ``y`` over times ``t``."""
    return float(np.sum(np.diff(t) * (y[1:] + y[:-1]) / 2.0))


def _abs(circuit, kind):
    add_precision_abs(circuit, "ABS1", "in", "out", BLOCK_R, kind)
    return np.abs


def _abs_negative(circuit, kind):
    add_precision_abs(circuit, "ABS1", "in", "out", BLOCK_R, kind, sign=-1)
    return lambda x: -np.abs(x)


def _abs_offset(circuit, kind):
    add_precision_abs(circuit, "ABS1", "in", "out", BLOCK_R, kind, offset_volts=-1.5)
    return lambda x: np.abs(x - 1.5)


def _dead_zone(circuit, kind):
    add_dead_zone(circuit, "DZ1", "in", "out", ETA, BLOCK_R, kind)
    return lambda x: dead_zone(x, ETA)


def _dead_zone_supplies(circuit, kind):
    add_dead_zone(circuit, "DZ1", "in", "out", ETA, BLOCK_R, kind, bias="supplies")
    return lambda x: dead_zone(x, ETA)


def _flange_from_two_abs(circuit, kind):
    # y - |y + eta| / 2 + |y - eta| / 2 with an inverting summer fed -y, +|y+eta| and
    # -|y-eta|: the paper's form of the flange force (divided by k).
    add_precision_abs(circuit, "ABS1", "in", "a1", BLOCK_R, kind, offset_volts=ETA)
    add_precision_abs(circuit, "ABS2", "in", "a2", BLOCK_R, kind, offset_volts=-ETA, sign=-1)
    circuit.add(
        Resistor("RS1", "nin", "sum", BLOCK_R),
        Resistor("RS2", "a1", "sum", 2 * BLOCK_R),
        Resistor("RS3", "a2", "sum", 2 * BLOCK_R),
        Resistor("RS4", "sum", "out", BLOCK_R),
    )
    add_opamp(circuit, "XSUM", "0", "sum", "out", kind)
    return lambda x: dead_zone(x, ETA)


BLOCKS = {
    "abs": _abs,
    "abs_negative": _abs_negative,
    "abs_offset": _abs_offset,
    "dead_zone": _dead_zone,
    "dead_zone_supplies": _dead_zone_supplies,  # tl074 only
    "flange_from_two_abs": _flange_from_two_abs,
}
"""Block benches: name -> build(circuit, kind) that adds the block from ``in`` (and ``nin``
= -in) to ``out`` and returns the reference function of v(in)."""


def transfer_curve(
    run_circuit: Callable[[Circuit], Waveforms], block: str, kind: str, points: int = 1000
):
    """The slow-ramp transfer curve of ``block``: (v(in), v(out), reference), V, shape (m,).

    ``points``: time-step limit of the ramp (duration / points); the tests use 1000 for speed,
    which under-samples the short glitches at the kinks, the report 4000.
    """
    circuit = ramp_circuit(FULL_SCALE, points=points)
    reference = BLOCKS[block](circuit, kind)
    waves = run_circuit(circuit)
    x = waves["in"]
    return x, waves["out"], reference(x)


def open_loop_deck() -> str:
    """The TL074 open loop driven by ``AC 1`` at its + input, ``.ac dec 100 1 100meg``."""
    body = SUPPLIES + "VP p 0 DC 0 AC 1\nXU p 0 vcc vee out TL074\n"
    return deck(body, ".ac dec 100 1 100meg")


def builtin_open_loop_magnitude() -> tuple[np.ndarray, np.ndarray]:
    """:func:`ngspice_open_loop_magnitude` by our engine's ``.ac``."""
    from circuitsim.netlist.reader import parse_netlist
    from circuitsim.solver import ac_analysis

    waves = ac_analysis(parse_netlist(open_loop_deck()), probes=["out"])
    return waves.time, waves["vm(out)"]


def ngspice_open_loop_magnitude(tmp_dir) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop |v(out)/v(in)| of the TL074 from an ngspice ``.ac`` sweep, 1 Hz .. 100 MHz.

    This runs ``ngspice -b`` directly and has it write the magnitude with ``wrdata`` (not the
    project's runner: the figure stays independent of our code). Returns (frequency Hz,
    magnitude V/V).
    """
    import subprocess
    from pathlib import Path

    out = Path(tmp_dir) / "ac.txt"
    text = open_loop_deck().replace(
        "\n.end\n", f"\n.control\nrun\nwrdata {out} vm(out)\n.endc\n.end\n"
    )
    path = Path(tmp_dir) / "ac.cir"
    path.write_text(text)
    # ngspice's exit status is not meaningful with a .control block; the data file is.
    done = subprocess.run(["ngspice", "-b", str(path)], capture_output=True, text=True, timeout=60)
    if not out.exists():
        raise RuntimeError(
            f"ngspice wrote no .ac data:\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
        )
    data = np.loadtxt(out, ndmin=2)
    return data[:, 0], data[:, 1]
