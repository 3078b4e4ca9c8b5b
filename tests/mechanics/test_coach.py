"""The shipped 15-DOF passenger coach (models/coach.toml, written as elements) against its
equations of motion typed again here with plain numpy.

The reference writes each body's equation (docs/model.md, "Shipped models", coach) as the
forces of its springs, dampers, creep and wheel-rail terms, takes M, C, K from them (the
forces are linear: their columns are the forces of unit displacements and rates), and never
touches the model file, its expression language or elements.py. The numbers are the file's
(Iwnicki 1998's vehicle 1 and the choices its comments state), typed again.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from circuitsim.mechanics import critical_speed, load_model, solve
from tests.conftest import requires_ngspice

P = dict(
    m_c=32000.0, I_cz=1.97e6, I_cx=5.68e4, m_b=2615.0, I_bz=3067.0, m_w=1813.0, I_wz=1120.0,
    l=9.5, a=1.28, r0=0.46, b=0.75, lam=0.15, f11=1.0e7, f22=1.0e7, g=9.81, k_r=1.7e7,
    eta=0.009, K_px=3.1391e7, K_py=3.884e6, b1=1.0, K_sy=1.6e5, K_sx=1.6e5, K_sz=4.3e5,
    C_sy=3.2e4, C_sz=2.0e4, C_yd=2.0e5, b2=1.0, b_yd=1.3, h=1.0,
)  # fmt: skip
NAMES = ["y1", "psi1", "y2", "psi2", "y3", "psi3", "y4", "psi4",
         "yb1", "psib1", "yb2", "psib2", "yc", "psic", "phic"]  # fmt: skip
WHEELSETS = [(1, 1, +1), (2, 1, -1), (3, 2, +1), (4, 2, -1)]  # (i, bogie j, s_i: ahead +1)
BOGIES = [(1, +1), (2, -1)]  # (j, sigma_j: front +1, at x = sigma_j l)


def forces(q, v, V):
    """C v + K q of the coach's 15 equations (N, N m), in the order of NAMES."""
    p = P
    W = p["g"] * (p["m_c"] + 2 * p["m_b"] + 4 * p["m_w"]) / 4  # axle load, N
    x = dict(zip(NAMES, q, strict=True))
    xd = dict(zip(NAMES, v, strict=True))
    out = dict.fromkeys(NAMES, 0.0)
    a, l, h = p["a"], p["l"], p["h"]
    for i, j, s in WHEELSETS:
        y, psi, yb, psib = x[f"y{i}"], x[f"psi{i}"], x[f"yb{j}"], x[f"psib{j}"]
        dy, dpsi = xd[f"y{i}"], xd[f"psi{i}"]
        primary_lateral = 2 * p["K_py"] * (y - yb - s * a * psib)
        primary_yaw = 2 * p["K_px"] * p["b1"] ** 2 * (psi - psib)
        out[f"y{i}"] += (2 * p["f22"] * (dy / V - psi) + W * p["lam"] / p["b"] * y
                         + primary_lateral)  # fmt: skip
        out[f"psi{i}"] += (2 * p["f11"] * p["b"] * (p["b"] * dpsi / V + p["lam"] * y / p["r0"])
                           - W * p["b"] * p["lam"] * psi + primary_yaw)  # fmt: skip
        out[f"yb{j}"] -= primary_lateral
        out[f"psib{j}"] -= s * a * primary_lateral + primary_yaw
    for j, sigma in BOGIES:
        # the secondary's lateral deflection: frame minus the body's point l ahead/behind
        # its centre and h below its centre of mass
        stretch = x[f"yb{j}"] - x["yc"] - sigma * l * x["psic"] + h * x["phic"]
        rate = xd[f"yb{j}"] - xd["yc"] - sigma * l * xd["psic"] + h * xd["phic"]
        lateral = 2 * p["K_sy"] * stretch + p["C_sy"] * rate
        yaw = (2 * p["K_sx"] * p["b2"] ** 2 * (x[f"psib{j}"] - x["psic"])
               + 2 * p["C_yd"] * p["b_yd"] ** 2 * (xd[f"psib{j}"] - xd["psic"]))  # fmt: skip
        out[f"yb{j}"] += lateral
        out[f"psib{j}"] += yaw
        out["yc"] -= lateral
        out["psic"] -= sigma * l * lateral + yaw
        out["phic"] += (h * lateral + 2 * p["K_sz"] * p["b2"] ** 2 * x["phic"]
                        + 2 * p["C_sz"] * p["b2"] ** 2 * xd["phic"])  # fmt: skip
    out["phic"] -= p["m_c"] * p["g"] * h * x["phic"]  # the body's weight tips it further
    return np.array([out[n] for n in NAMES])


def reference_matrices(V):
    """M, C, K of the equations above (shape (15, 15) each)."""
    n = len(NAMES)
    unit = np.eye(n)
    K = np.column_stack([forces(unit[k], np.zeros(n), V) for k in range(n)])
    C = np.column_stack([forces(np.zeros(n), unit[k], V) for k in range(n)])
    p = P
    M = np.diag([p["m_w"], p["I_wz"]] * 4 + [p["m_b"], p["I_bz"]] * 2
                + [p["m_c"], p["I_cz"], p["I_cx"]])  # fmt: skip
    return M, C, K


def reference_A(V):
    M, C, K = reference_matrices(V)
    n = len(NAMES)
    inverse = np.linalg.inv(M)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-inverse @ K, -inverse @ C]])


def model_matrices(model, V):
    """M, C, K as the model file's elements assemble them, evaluated at speed V."""
    _, values, coefficients = model.environment(parameters={"V": V})
    env = {**values, **coefficients}
    return [
        np.array([[item.expression(env) for item in row] for row in model.spec.matrices[name]])
        for name in ("M", "C", "K")
    ]


@pytest.fixture(scope="module")
def coach():
    return load_model("coach")


@pytest.mark.parametrize("V", [30.0, 93.0, 110.0])
def test_the_elements_assemble_the_matrices_of_the_equations(coach, V):
    for ours, theirs, name in zip(
        model_matrices(coach, V), reference_matrices(V), "MCK", strict=True
    ):
        scale = np.max(np.abs(theirs))
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-14 * scale, err_msg=name)
        assert np.array_equal(ours != 0, theirs != 0), name  # the same sparsity
    assert len(coach.coordinates) == 15 and coach.n == 30
    A = coach.system(parameters={"V": V}).A
    np.testing.assert_allclose(A, reference_A(V), rtol=1e-12, atol=1e-12 * np.max(np.abs(A)))


def test_eigenvalues_and_critical_speed_agree_with_the_reference(coach):
    for V in (50.0, 93.0, 110.0):
        ours = np.sort_complex(np.linalg.eigvals(coach.system(parameters={"V": V}).A))
        theirs = np.sort_complex(np.linalg.eigvals(reference_A(V)))
        np.testing.assert_allclose(ours, theirs, rtol=1e-10)

    def rate(V):
        return np.max(np.linalg.eigvals(reference_A(V)).real)

    assert rate(90.0) < 0 < rate(100.0)
    V_c = brentq(rate, 90.0, 100.0, xtol=1e-13, rtol=1e-15)
    speed, frequency = critical_speed(coach, None)
    assert speed == pytest.approx(V_c, rel=1e-10)
    at_critical = np.linalg.eigvals(reference_A(V_c))
    hunting = at_critical[np.argmax(at_critical.real)]
    assert frequency == pytest.approx(abs(hunting.imag) / (2 * np.pi), rel=1e-8)
    assert 93.0 < speed < 94.0 and 3.9 < frequency < 4.1  # the file's comments say so


def flange(y):
    return P["k_r"] * (y - np.clip(y, -P["eta"], P["eta"]))


def scipy_solution(V, t_stop):
    """The coach's equations with the flanges, from a 5 mm push of y1, by solve_ivp."""
    M, C, K = reference_matrices(V)
    inverse = np.linalg.inv(M)
    n = len(NAMES)

    def rhs(t, x):
        q, v = x[:n], x[n:]
        contact = np.zeros(n)
        contact[0:8:2] = flange(q[0:8:2])
        return np.concatenate([v, -inverse @ (C @ v + K @ q + contact)])

    x0 = np.zeros(2 * n)
    x0[0] = 0.005
    return solve_ivp(rhs, (0, t_stop), x0, method="DOP853", rtol=1e-11, atol=1e-13,
                     max_step=5e-4, dense_output=True)  # fmt: skip


def worst_nrmsd_percent(ours, theirs, t_stop):
    t = np.linspace(0, t_stop, 20001)
    x_ours, x_theirs = ours.sol(t), theirs.sol(t)
    errors = np.sqrt(np.mean((x_ours - x_theirs) ** 2, axis=1)) / np.ptp(x_theirs, axis=1)
    return 100 * np.max(errors)


@pytest.mark.slow
def test_the_hunting_case_grows_into_a_flange_limited_cycle_as_scipy_solves_it(coach):
    """V = 110 m/s (above the critical 93.4 m/s), a 5 mm push of the leading wheelset."""
    V, t_stop = 110.0, 3.0
    theirs = scipy_solution(V, t_stop)
    system = coach.system()
    assert system.parameters["V"] == V and system.x0[0] == 0.005
    ours = solve(system, (0, t_stop))
    assert worst_nrmsd_percent(ours, theirs, t_stop) < 1e-4
    t = np.linspace(0, t_stop, 6001)
    x_theirs = theirs.sol(t)
    late = t > 2.0
    for i in range(4):  # every wheelset rides on its flanges, held there: a limit cycle
        peak = np.max(np.abs(x_theirs[2 * i, late]))
        assert P["eta"] < peak < P["eta"] + 0.004, NAMES[2 * i]
    assert len(ours.kinks) > 100


@pytest.mark.slow
def test_a_shallow_flange_contact_is_not_missed(coach):
    """At V = 98.5 m/s wheelset 1 touches its flange 54 um deep for 8 ms (3.9739-3.9822 s),
    inside one step of the direct solution: the crossing check inside each step finds it."""
    V, t_stop = 98.5, 6.0
    ours = solve(coach.system(parameters={"V": V}), (0, t_stop))
    assert worst_nrmsd_percent(ours, scipy_solution(V, t_stop), t_stop) < 1e-4


@pytest.mark.slow
@requires_ngspice
@pytest.mark.parametrize("engine", ["builtin", "ngspice"])
def test_compare_passes_at_the_hunting_case(engine, tmp_path):
    import json
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-m", "circuitsim", "compare", "--model", "coach", "--engine", engine,
         "--json"],
        capture_output=True, text=True, timeout=900, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads(done.stdout)
    assert report["passed"] and len(report["states"]) == 30
    worst = max(state["nrmsd_percent"] for state in report["states"].values())
    assert worst < 0.1  # measured 0.056 % (y2_dot) on both engines; the threshold is 0.5 %
