"""The bench's JSON API on a running ``circuitsim bench`` (the wheelset at 57 m/s from a
5 mm push, stepping as fast as it can, run to known model times with ``until``): state,
knobs, pushes, traces, history, export, and HTTP 400 for bad values."""

import json

import numpy as np
import pytest

from circuitsim.compare.signals import nrmsd_percent
from tests.bench.live import request, run_until, wait_for_model_time

STATES = ["y", "psi", "y_dot", "psi_dot"]


def test_state_says_time_knobs_and_running(bench_57):
    status, state = request(bench_57 + "api/state")
    assert status == 200
    assert state["running"] is False and state["t"] == 0.0 and state["error"] is None  # --paused
    assert state["knobs"]["speed"] == 57.0 and state["knobs"]["flange"] is False
    assert state["knobs"]["amplitude"] == 0.0
    assert {k["name"]: k["parts"] for k in state["knob_info"]}["speed"] == ["R33", "R44"]


def test_the_speed_knob_restamps_r33_r44_and_the_run_carries_on(bench_57):
    run_until(bench_57, 1.0)
    status, answer = request(bench_57 + "api/knobs", {"speed": 54})
    assert status == 200
    t_applied = answer["t_applied"]
    assert t_applied == 1.0  # held there: the change acts at a known model time
    state = run_until(bench_57, t_applied + 0.5)
    assert state["knobs"]["speed"] == 54.0
    _, history = request(bench_57 + "api/history")
    change = [e for e in history["events"] if e["kind"] == "knobs"][-1]
    assert change["t"] == t_applied and change["values"] == {"speed": 54}
    for old, new in change["resistors"].values():  # R33, R44 proportional to V
        assert new / old == pytest.approx(54 / 57, rel=1e-9)
    _, trace = request(bench_57 + f"api/trace?since={t_applied}")
    assert trace["t"][0] > t_applied and set(trace["states"]) == set(trace["ode"]) == set(STATES)
    # the samples after the change continue the ones before it: no restart from y0
    _, before = request(bench_57 + f"api/trace?since={t_applied - 0.01}")
    assert before["t"][0] < t_applied < before["t"][-1]


def test_the_trace_is_the_circuit_beside_the_ode(bench_57):
    run_until(bench_57, 2.0)
    _, trace = request(bench_57 + "api/trace?since=0")
    for name in STATES:
        circuit, ode = np.array(trace["states"][name]), np.array(trace["ode"][name])
        assert len(circuit) == len(ode) == len(trace["t"])
        assert nrmsd_percent(ode, circuit) < 0.5


def test_a_push_is_applied_at_a_chunk_boundary(bench_57):
    status, answer = request(bench_57 + "api/set_state", {"psi": 0.001})
    assert status == 200
    _, history = request(bench_57 + "api/history")
    push = history["events"][-1]
    assert push == {**push, "kind": "state", "t": answer["t_applied"], "values": {"psi": 0.001}}
    assert answer["t_applied"] / history["chunk_s"] == pytest.approx(
        round(answer["t_applied"] / history["chunk_s"]), abs=1e-9
    )


@pytest.mark.parametrize(
    "path, body, message",
    [
        ("api/knobs", {"speed": "fast"}, "finite number"),
        ("api/knobs", {"speed": -57}, "wiring"),
        ("api/knobs", {"nope": 1}, "unknown knob"),
        ("api/knobs", b"{not json", "not JSON"),
        ("api/knobs", b"NaN", "JSON object"),
        ("api/knobs", {"flange": "on"}, "true or false"),
        ("api/set_state", {"q": 1}, "unknown state"),
        ("api/set_state", {"y": None}, "finite number"),
        ("api/run", {"rate": -1}, "positive"),
        ("api/run", {"running": "yes"}, "true or false"),
        ("api/run", {"running": True, "until": "soon"}, "until must be"),
        ("api/run", {"until": 1e400}, "until must be"),
        ("api/trace?since=abc", None, "since must be a number"),
    ],
)
def test_bad_values_get_400_with_a_message(bench_57, path, body, message):
    _, before = request(bench_57 + "api/state")
    status, answer = request(bench_57 + path, body)
    assert status == 400
    assert message in answer["error"]
    _, after = request(bench_57 + "api/state")
    assert after["knobs"] == before["knobs"]
    assert (after["running"], after["rate"]) == (before["running"], before["rate"])


def test_pause_holds_the_clock_and_resume_runs_it(bench_57):
    status, state = request(bench_57 + "api/run", {"running": False})
    assert status == 200 and state["running"] is False
    wait = request(bench_57 + "api/state")[1]["t"]  # the chunk in progress has ended
    _, later = request(bench_57 + "api/state")
    assert later["t"] == wait and later["running"] is False
    _, state = request(bench_57 + "api/run", {"running": True, "rate": 1e9})
    assert state["running"] is True and state["rate"] == 1e9
    wait_for_model_time(bench_57, wait + 0.2)


def test_export_gives_the_traces_and_the_history(bench_57):
    status, csv_text = request(bench_57 + "api/export/trace.csv")
    assert status == 200
    lines = csv_text.splitlines()
    assert lines[0].startswith("time_s,y_circuit_m,y_ode_m,psi_circuit_rad")
    assert float(lines[1].split(",")[0]) == 0.0
    status, history = request(bench_57 + "api/export/history.json")
    assert status == 200
    events = (history if isinstance(history, dict) else json.loads(history))["events"]
    assert events[0]["kind"] == "start" and events[0]["state"]["y"] == 0.005
