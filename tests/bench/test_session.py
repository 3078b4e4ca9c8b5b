"""A bench session through the library (no browser, unthrottled): the circuit with a knob
history against the ODE solved independently with the same piecewise-constant values, the
wheelset's free response against MODEL.md, and refused knob values."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from circuitsim.bench.errors import BenchError
from circuitsim.bench.knobs import BenchSetup
from circuitsim.bench.running import Overload
from circuitsim.bench.session import BenchSession
from circuitsim.compare.signals import nrmsd_percent
from circuitsim.mechanics import load_model
from circuitsim.mechanics.solve import solve
from circuitsim.synthesis.knob import KnobRequest
from circuitsim.synthesis.options import SynthesisOptions

ROOT = Path(__file__).resolve().parents[2]

#: (model seconds, knob changes at the segment's start, push at its start)
HISTORY = [
    (3.0, {}, {"y": 0.005}),
    (3.0, {"speed": 54.0}, {}),
    (2.0, {"flange": True, "amplitude": 0.04, "freq": 5.0}, {}),
]


def wheelset_setup(speed=57.0) -> BenchSetup:
    """The paper's wheelset at ``speed``, no forcing, flange off; ideal op-amps, exact values."""
    model = load_model(None)
    system = model.system(None, {"V": speed, "a": 0.0}, {"flange": False})
    return BenchSetup.from_system(model, system, SynthesisOptions(series="exact"))


def reference(history, t_end) -> tuple[np.ndarray, np.ndarray]:
    """The ODE with the same piecewise-constant values, solved here segment by segment with
    the model's own systems (the flange term absent when off, not the bench's never-closing
    switch), sampled every 2 ms."""
    model = load_model(None)
    values = {"V": 57.0, "a": 0.0, "f": 3.0}
    flange, x = False, np.zeros(4)
    names = {"speed": "V", "amplitude": "a", "freq": "f"}
    t0, times, states = 0.0, [], []
    for duration, knobs, push in history:
        for name, value in knobs.items():
            if name == "flange":
                flange = value
            else:
                values[names[name]] = value
        for name, value in push.items():
            x[["y", "psi", "y_dot", "psi_dot"].index(name)] = value
        system = model.system(None, values, {"flange": flange})
        result = solve(system, (t0, t0 + duration), x0=x)
        grid = t0 + 0.002 * np.arange(1, round(duration / 0.002) + 1)
        times.append(grid)
        states.append(result.sol(grid))
        x = result.x[:, -1]
        t0 += duration
    return np.concatenate(times), np.concatenate(states, axis=1)


@pytest.fixture(scope="module")
def session_run():
    """The session stepped through HISTORY as fast as it runs."""
    session = BenchSession(wheelset_setup())
    applied = []
    for duration, knobs, push in HISTORY:
        if knobs:
            applied.append(session.set_knobs(knobs))
        if push:
            applied.append(session.set_state(push))
        for _ in range(round(duration / session.chunk)):
            session.step()
    return session, applied


def test_the_circuit_follows_the_ode_with_the_same_knob_history(session_run):
    """Every state within 0.5 % NRMSD of the ODE solved independently with the same knob
    history (ideal op-amps, exact values)."""
    session, _ = session_run
    data = session.trace(since=0.0)
    t_ref, x_ref = reference(HISTORY, session.t)
    np.testing.assert_allclose(data["t"], t_ref, rtol=0, atol=1e-9)
    for i, name in enumerate(session.states):
        error = nrmsd_percent(x_ref[i], np.array(data["states"][name]))
        assert error < 0.5, f"{name}: {error:.3f} % NRMSD"
        # the session's own ODE is that reference (to the solvers' tolerance)
        assert nrmsd_percent(x_ref[i], np.array(data["ode"][name])) < 1e-4
    running = session.nrmsd()
    assert all(0 < value < 0.5 for value in running.values()), running


def test_hunting_grows_at_57_and_decays_after_the_knob_goes_to_54(session_run):
    """The issue's bench demo: a 5 mm push at 57 m/s grows (the critical speed is
    55.6455 m/s, MODEL.md), turning the speed to 54 m/s makes it decay, with no restart."""
    session, applied = session_run
    data = session.trace(since=-1.0)
    t, y = np.array(data["t"]), np.abs(data["states"]["y"])

    def peak(a, b):
        return y[(t > a) & (t <= b)].max()

    assert peak(2.0, 3.0) > 2 * peak(0.0, 1.0)  # growing at 57 m/s
    assert peak(5.0, 6.0) < 0.5 * peak(3.0, 4.0)  # decaying at 54 m/s
    assert applied == pytest.approx([0.0, 3.0, 6.0])
    # one uniform clock from 0: nothing restarted
    np.testing.assert_allclose(np.diff(t), session.sample, rtol=1e-6)


def test_the_speed_knob_turns_r33_and_r44_in_proportion(session_run):
    """c_y and c_psi are proportional to 1/V, so R33 and R44 to V (MODEL.md)."""
    session, _ = session_run
    speed = next(k for k in session.knobs if k.name == "speed")
    assert set(speed.parts) == {"R33", "R44"}
    change = next(e for e in session.history if e["kind"] == "knobs")
    assert set(change["resistors"]) == {"R33", "R44"}
    for old, new in change["resistors"].values():
        assert new / old == pytest.approx(54.0 / 57.0, rel=1e-9)


def test_export_holds_every_sample_and_the_history(session_run):
    session, _ = session_run
    lines = session.trace_csv().splitlines()
    assert lines[0].split(",")[:3] == ["time_s", "y_circuit_m", "y_ode_m"]
    assert len(lines) == 1 + 1 + round(session.t / session.sample)
    events = json.loads(session.history_json())["events"]
    assert [e["kind"] for e in events] == ["start", "state", "knobs", "knobs"]
    assert events[3]["values"] == {"flange": True, "amplitude": 0.04, "freq": 5.0}


def test_trace_since_returns_only_newer_samples(session_run):
    session, _ = session_run
    data = session.trace(since=7.5, last=0.1)
    assert data["t"][0] > 7.9 - 1e-9 and data["t"][-1] == pytest.approx(8.0)
    assert len(data["t"]) == len(data["states"]["psi"]) == len(data["ode"]["y_dot"]) == 50


@pytest.mark.slow
def test_free_response_at_57_matches_model_md():
    """MODEL.md: from y(0) = 5 mm at V = 57, no flange, no excitation, max |y| over 9-10 s
    is 1.223 m."""
    session = BenchSession(wheelset_setup(57.0), chunk=0.1, overload=math.inf)  # 68 V at 10 s
    session.set_state({"y": 0.005})
    while session.t < 10.0 - 1e-9:
        session.step()
    data = session.trace(since=9.0)
    assert np.max(np.abs(data["states"]["y"])) == pytest.approx(1.223, rel=1e-2)


@pytest.fixture(scope="module")
def idle_session():
    return BenchSession(wheelset_setup())


@pytest.mark.parametrize(
    "values, message",
    [
        ({"speed": "fast"}, "finite number"),
        ({"speed": math.nan}, "finite number"),
        ({"speed": math.inf}, "finite number"),
        ({"flange": 1}, "true or false"),
        ({"nope": 1}, "unknown knob 'nope'"),
        ({}, "JSON object"),
        ([57], "JSON object"),
        ({"speed": -57.0}, "wiring"),  # negative damping: R33 would move to the other node
    ],
)
def test_bad_knob_values_are_refused_and_change_nothing(idle_session, values, message):
    before = (idle_session.knob_values(), len(idle_session.history), idle_session.resistors)
    with pytest.raises(BenchError, match=message):
        idle_session.set_knobs(values)
    assert (idle_session.knob_values(), len(idle_session.history), idle_session.resistors) == (
        before
    )


@pytest.mark.parametrize(
    "values, message",
    [({"q": 1.0}, "unknown state 'q'"), ({"y": "x"}, "finite number"), ({}, "JSON object")],
)
def test_bad_pushes_are_refused(idle_session, values, message):
    with pytest.raises(BenchError, match=message):
        idle_session.set_state(values)


def test_a_diverging_circuit_stops_at_the_overload_and_goes_on_after_a_push():
    """At 57 m/s without the flange the hunting grows without bound (to 1e12 V, where the
    engine fails, at 53.7 s from 5 mm): past a real op-amp's swing the chunk is refused,
    nothing changes, and a push back lets the session go on."""
    session = BenchSession(wheelset_setup(57.0), chunk=0.1)
    volts_per_metre = session.scale_map.states["y"].volts_per_unit
    session.set_state({"y": 12.0 / volts_per_metre})  # 12 V, just inside the 13 V swing
    with pytest.raises(Overload) as failure:
        for _ in range(50):
            session.step()
    t, samples, state = session.t, session.trace()["t"], session.circuit.states().copy()
    reached = re.search(r"state \w+'s node \S+ reached (\S+) V", str(failure.value))
    assert reached and 13.0 < float(reached.group(1)) < 20.0
    assert f"model time {t:.3g}" in str(failure.value) or t < 5.0
    with pytest.raises(Overload):  # the same chunk again: the same refusal, nothing changed
        session.step()
    assert session.t == t and session.trace()["t"] == samples
    assert np.array_equal(session.circuit.states(), state)
    session.set_state({"y": 0.005, "psi": 0.0, "y_dot": 0.0, "psi_dot": 0.0})
    session.step()
    assert session.t == pytest.approx(t + session.chunk)
    assert np.max(np.abs(session.trace(since=t)["states"]["y"])) < 0.01


def test_time_series_forcing_is_refused():
    model = load_model(None)
    system = model.system(None, {"V": 55.0}, forcing={"irregularity": True, "track": False})
    setup = BenchSetup.from_system(model, system, SynthesisOptions(series="exact"))
    with pytest.raises(BenchError, match="sinusoidal forcing only"):
        BenchSession(setup)


def test_a_model_file_may_list_its_knobs(tmp_path):
    """``[circuit] knobs = [...]``: only those parameters (beside the scenario options and
    the switches) become knobs."""
    text = (ROOT / "circuitsim/mechanics/models/wheelset.toml").read_text()
    series = ROOT / "circuitsim/mechanics/models/track_irregularity.csv"
    text = text.replace("[circuit]\n", '[circuit]\nknobs = ["k"]\n', 1)
    text = text.replace('file = "track_irregularity.csv"', f'file = "{series}"')
    path = tmp_path / "wheelset_knobs.toml"
    path.write_text(text)
    model = load_model(str(path))
    system = model.system(None, {"V": 57.0, "a": 0.0})
    session = BenchSession(BenchSetup.from_system(model, system, SynthesisOptions(series="exact")))
    assert [k.name for k in session.knobs] == ["speed", "freq", "amplitude", "flange", "k"]
    assert next(k for k in session.knobs if k.name == "k").parts == ("R3",)


def test_with_a_speed_range_the_speed_knob_turns_potentiometer_dials():
    """--speed-range 40:70: R33 = R33A (fixed, E96) + R33P (a potentiometer); the speed knob
    turns only the potentiometers, their sum stays proportional to V, and a speed past the
    dial's range is refused."""
    model = load_model(None)
    system = model.system(None, {"V": 57.0, "a": 0.0}, {"flange": False})

    def linear_part(value):
        return model.system(None, {"V": value, "a": 0.0}, {"flange": False}).A

    pot = KnobRequest("V", 40.0, 70.0, linear_part, "m/s", "E6")
    setup = BenchSetup.from_system(model, system, SynthesisOptions(series="E96"), pot=pot)
    session = BenchSession(setup)
    speed = next(k for k in session.knobs if k.name == "speed")
    assert speed.parts == ("R33P", "R44P")
    before = session.pot_settings()
    session.set_knobs({"speed": 54.0})
    after = session.pot_settings()
    for name in ("R33", "R44"):
        old, new = before[name], after[name]
        assert new["fixed"] == old["fixed"] and new["pot"] == old["pot"]
        total = [s["fixed"] + s["dial"] * s["pot"] for s in (old, new)]
        assert total[1] / total[0] == pytest.approx(54.0 / 57.0, rel=1e-9)
        assert 0 < new["dial"] < old["dial"] < 1
    with pytest.raises(BenchError, match="outside the knob's range 40:70"):
        session.set_knobs({"speed": 75.0})


def test_a_time_scaled_circuit_keeps_the_generator_on_model_time():
    """K = 10 (one model second in 0.1 circuit seconds): the forcing's phase at each chunk is
    2 pi f t of the model time reached, also across a frequency change."""
    history = [
        (1.0, {"flange": True, "amplitude": 0.04, "freq": 5.0}, {"y": 0.005}),
        (1.0, {"freq": 3.0}, {}),
    ]
    model = load_model(None)
    system = model.system(None, {"V": 57.0, "a": 0.0}, {"flange": False})
    options = SynthesisOptions(series="exact", time_scale=10.0)
    session = BenchSession(BenchSetup.from_system(model, system, options))
    assert session.scale_map.time_scale == 10.0
    for duration, knobs, push in history:
        session.set_knobs(knobs)
        if push:
            session.set_state(push)
        for _ in range(round(duration / session.chunk)):
            session.step()
    data = session.trace(since=0.0)
    _, x_ref = reference(history, session.t)
    for i, name in enumerate(session.states):
        assert nrmsd_percent(x_ref[i], np.array(data["states"][name])) < 0.5, name
