"""Knobs through derived parameters: the shipped bogie's speed enters only through
``c_y = "2*f22/V"`` and ``c_psi = "2*f11*b**2/V"``. Turning the speed knob must move the
resistors that realize them and the hunting of both the circuit and the bench's ODE, checked
against the bogie's equations typed again here and solved with scipy at the new speed."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from circuitsim.bench.errors import BenchError
from circuitsim.bench.knobs import BenchSetup
from circuitsim.bench.session import BenchSession
from circuitsim.mechanics import load_model
from circuitsim.synthesis.options import SynthesisOptions

#: The bogie's numbers (circuitsim/mechanics/models/bogie.toml), typed again.
BOGIE = dict(m=1500.0, I=1200.0, lam=0.3, b=0.74, b1=1.05, r0=0.44, W=21600.0, Ky=2.4e6,
             Kx=2.8e6, f11=3.98e6, f22=3.62e6, a=1.25, m_b=2600.0, I_b=1500.0, K_sy=3.0e5,
             C_sy=3.0e4, K_spsi=2.4e5, C_spsi=6.0e5)  # fmt: skip
STATES = ("y1", "psi1", "y2", "psi2", "yb", "psib")


def bogie_matrix(V: float) -> np.ndarray:
    """The bogie's first-order state matrix at speed V (m/s), flange and track off, from
    the equations of the model file's header."""
    p = BOGIE
    c_y, c_psi = 2 * p["f22"] / V, 2 * p["f11"] * p["b"] ** 2 / V
    k_g, k_psiy = p["W"] * p["lam"] / p["b"], 2 * p["f11"] * p["b"] * p["lam"] / p["r0"]
    k_yp, k_pp, a = 2 * p["Ky"], 2 * p["Kx"] * p["b1"] ** 2, p["a"]
    gyaw = k_pp - p["W"] * p["b"] * p["lam"]
    M = np.diag([p["m"], p["I"], p["m"], p["I"], p["m_b"], p["I_b"]])
    C = np.diag([c_y, c_psi, c_y, c_psi, p["C_sy"], p["C_spsi"]])
    K = np.array([
        [k_g + k_yp, -2 * p["f22"], 0, 0, -k_yp, -k_yp * a],
        [k_psiy, gyaw, 0, 0, 0, -k_pp],
        [0, 0, k_g + k_yp, -2 * p["f22"], -k_yp, k_yp * a],
        [0, 0, k_psiy, gyaw, 0, -k_pp],
        [-k_yp, 0, -k_yp, 0, p["K_sy"] + 2 * k_yp, 0],
        [-k_yp * a, -k_pp, k_yp * a, -k_pp, 0, p["K_spsi"] + 2 * k_yp * a**2 + 2 * k_pp],
    ])  # fmt: skip
    A = np.zeros((12, 12))
    A[:6, 6:] = np.eye(6)
    A[6:, :6] = -np.linalg.solve(M, K)
    A[6:, 6:] = -np.linalg.solve(M, C)
    return A


def bogie_setup(speed: float) -> BenchSetup:
    model = load_model("bogie")
    system = model.system(
        None, {"V": speed, "A_t": 0.0}, {"flange1": False, "flange2": False}, x0={"y1": 0.005}
    )
    return BenchSetup.from_system(model, system, SynthesisOptions(series="exact"))


def test_derived_parameters_are_no_knobs_and_follow_the_speed():
    session = BenchSession(bogie_setup(60.0))
    names = [k.name for k in session.knobs]
    for derived in ("c_y", "c_psi", "k_g", "k_psiy", "k_yp", "k_pp", "omega", "Q_lat"):
        assert derived not in names
    assert session.system.parameters["c_y"] == pytest.approx(2 * 3.62e6 / 60.0, rel=1e-15)
    session.set_knobs({"speed": 75.0})
    assert session.system.parameters["c_y"] == pytest.approx(2 * 3.62e6 / 75.0, rel=1e-15)
    assert np.allclose(session.system.A, bogie_matrix(75.0), rtol=1e-12, atol=1e-9)


def test_the_speed_knob_moves_the_bogies_hunting_in_circuit_and_ode():
    """60 m/s (below the critical 67.16 m/s: decaying) for 1 s, then the knob to 75 m/s
    (growing): the resistors of c_y and c_psi (R = scale / |A|, so proportional to V) move
    by 75/60, and after the turn both the circuit and the bench's ODE follow the typed
    equations at 75 m/s from the state reached, not those at 60 m/s."""
    session = BenchSession(bogie_setup(60.0), chunk=0.1)
    for _ in range(10):
        session.step()
    t_turn = session.t
    x_turn = session.x_ode.copy()
    session.set_knobs({"speed": 75.0})
    changed = session.history[-1]["resistors"]
    # c_y and c_psi of each wheelset (A[y_i', y_i'], A[psi_i', psi_i']: R proportional to V);
    # the rest are the track generators' input resistors (Q_lat follows c_y), here at 0 m
    damping = {n for n, (old, new) in changed.items() if math.isclose(new / old, 75 / 60)}
    assert len(damping) == 4
    assert all("_F" in name for name in set(changed) - damping)
    for _ in range(20):
        session.step()
    data = session.trace(since=t_turn)
    t = np.array(data["t"])

    def fresh(V):
        A = bogie_matrix(V)
        result = solve_ivp(lambda _, x: A @ x, (t_turn, t[-1]), x_turn, t_eval=t,
                           rtol=1e-10, atol=1e-14, method="DOP853")  # fmt: skip
        return result.y

    at_75, at_60 = fresh(75.0), fresh(60.0)
    y1 = STATES.index("y1")
    span = np.ptp(at_75[y1])
    for side, within in (("states", 1e-3), ("ode", 1e-6)):  # the circuit; the bench's ODE
        trace = np.array(data[side]["y1"])
        assert np.sqrt(np.mean((trace - at_75[y1]) ** 2)) / span < within, side
        assert np.sqrt(np.mean((trace - at_60[y1]) ** 2)) / span > 0.05, side
    # the growth: the eigenvalue of the typed equations at 75 m/s is unstable, at 60 stable
    assert np.max(np.linalg.eigvals(bogie_matrix(75.0)).real) > 0
    assert np.max(np.linalg.eigvals(bogie_matrix(60.0)).real) < 0


def test_a_knob_that_moves_no_resistor_is_refused(tmp_path):
    """A speed that enters only a derived parameter the scenario pinned (``--param
    c=...``) changes nothing: the knob is refused with the reason, nothing changes."""
    path = tmp_path / "pinned.toml"
    path.write_text(
        '[model]\nname = "pinned"\nkind = "second_order"\n'
        '[coordinates]\nnames = ["y"]\nunits = ["m"]\n'
        '[parameters]\nV = { value = 20.0, unit = "m/s" }\nm = 2.0\nk = 800.0\n'
        'c = { value = "40/V" }\n'
        '[options]\nspeed = "V"\n'
        '[matrices]\nM = [["m"]]\nC = [["c"]]\nK = [["k"]]\n'
    )
    model = load_model(str(path))
    system = model.system(None, {"c": 3.0}, x0={"y": 0.01})
    setup = BenchSetup.from_system(model, system, SynthesisOptions(series="exact"))
    assert setup.parameters["c"] == 3.0 and "c" in setup.parameters
    session = BenchSession(setup)
    before = (session.knob_values(), len(session.history), session.resistors)
    with pytest.raises(BenchError, match=r"knob 'speed' \(V 20 -> 30 m/s\) changes no resistor"):
        session.set_knobs({"speed": 30.0})
    assert (session.knob_values(), len(session.history), session.resistors) == before
    # without the pin, the speed moves the damping resistor
    free = BenchSession(
        BenchSetup.from_system(model, model.system(None, {}, x0={"y": 0.01}),
                               SynthesisOptions(series="exact"))
    )  # fmt: skip
    free.set_knobs({"speed": 30.0})
    ((old, new),) = free.history[-1]["resistors"].values()
    assert new / old == pytest.approx(1.5, rel=1e-9)
    assert math.isclose(free.system.parameters["c"], 40 / 30, rel_tol=1e-15)
