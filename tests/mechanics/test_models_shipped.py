"""The shipped models against their equations written out here by hand and solved by scipy.

Each reference below is the model's equations typed again from docs/model.md ("Shipped
models") with plain numpy (dead zones with np.clip, the creep law with np.tanh itself, not its
fit) and integrated by solve_ivp; none of it goes through the model file, its language or our
solver. The numbers are MODEL.md's (the wheelset) and the files' own (frame, suspension).
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from circuitsim.mechanics import critical_speed, load_model, solve
from circuitsim.mechanics.modelfile import shipped_models

# MODEL.md: the wheelset, Table 1, the flange
m, I, lam, b, b1, r0, W = 1500.0, 1200.0, 0.3, 0.74, 1.05, 0.44, 21600.0
Ky, Kx, f11, f22, k_fl, eta = 2.4e6, 2.8e6, 3.98e6, 3.62e6, 1.7e7, 0.009


def flange(y):
    return k_fl * (y - np.clip(y, -eta, eta))


def reference(rhs, n, t_stop):
    return solve_ivp(rhs, (0, t_stop), np.zeros(n), method="DOP853", rtol=1e-11, atol=1e-13,
                     max_step=5e-4, dense_output=True)  # fmt: skip


def nrmsd_percent(ours, theirs):
    return 100 * np.sqrt(np.mean((ours - theirs) ** 2)) / np.ptp(theirs)


def test_every_shipped_model_loads_by_name():
    assert {"wheelset", "bogie", "wheelset_creep", "quarter_car"} <= set(shipped_models())
    for name in shipped_models():
        assert load_model(name).name == name


def bogie_rhs(V=30.0, f=2.0, A_t=0.010):
    a, m_b, I_b = 1.25, 2600.0, 1500.0
    K_sy, C_sy, K_spsi, C_spsi = 3.0e5, 3.0e4, 2.4e5, 6.0e5
    k_g, omega = W * lam / b, 2 * np.pi * f
    tau = 2 * a / V  # the trailing wheelset meets the alignment 2a/V later

    def rhs(t, x):
        y1, p1, y2, p2, yb, pb = x[:6]
        v = x[6:]
        acc = np.zeros(6)
        for i, (y, p, s) in enumerate(((y1, p1, 1.0), (y2, p2, -1.0))):
            yt = A_t * np.sin(omega * (t - i * tau))  # track under wheelset i
            vt = A_t * omega * np.cos(omega * (t - i * tau))
            dy, dp = v[2 * i], v[2 * i + 1]
            lateral = (-2 * f22 * ((dy - vt) / V - p) - k_g * (y - yt)
                       - 2 * Ky * (y - yb - s * a * pb) - flange(y))  # fmt: skip
            yaw = (-2 * f11 * b * (b * dp / V + lam * (y - yt) / r0) + W * b * lam * p
                   - 2 * Kx * b1**2 * (p - pb))  # fmt: skip
            acc[2 * i], acc[2 * i + 1] = lateral / m, yaw / I
        primary = [(2 * Ky * (yb + s * a * pb - y), s) for y, s in ((y1, 1.0), (y2, -1.0))]
        acc[4] = (-C_sy * v[4] - K_sy * yb - sum(force for force, _ in primary)) / m_b
        acc[5] = (-C_spsi * v[5] - K_spsi * pb - sum(s * a * force for force, s in primary)
                  - 2 * Kx * b1**2 * ((pb - p1) + (pb - p2))) / I_b  # fmt: skip
        return np.concatenate([v, acc])

    return rhs


def test_bogie_matches_its_equations_solved_by_scipy():
    model = load_model("bogie")
    system = model.system()
    assert system.parameters["V"] == 30.0 and system.parameters["A_t"] == 0.010
    ours = solve(system, (0, 3.0))
    theirs = reference(bogie_rhs(), 12, 3.0)
    t = np.linspace(0, 3.0, 3001)
    x_ours, x_theirs = ours.sol(t), theirs.sol(t)
    for k, state in enumerate(system.states):
        assert nrmsd_percent(x_ours[k], x_theirs[k]) < 1e-4, state
    assert np.max(np.abs(x_theirs[0])) > eta and len(ours.kinks) > 10  # the flanges are struck


def test_bogie_linear_stability_from_its_own_matrices():
    # the critical speed from the file against the eigenvalues of the hand-built linear part
    speed, _ = critical_speed(load_model("bogie"), None)
    rhs_at = {v: bogie_rhs(V=v, A_t=0.0) for v in (speed - 0.01, speed + 0.01)}
    growth = {}
    for v, rhs in rhs_at.items():
        # finite differences of the (linear, unforced, flange-free inside the clearance) field
        jac = np.column_stack([(rhs(0.0, e * 1e-6) - rhs(0.0, -e * 1e-6)) / 2e-6
                               for e in np.eye(12)])  # fmt: skip
        growth[v] = np.max(np.linalg.eigvals(jac).real)
    assert growth[speed - 0.01] < 0 < growth[speed + 0.01]


def creep_rhs(V=55.0, f=5.0, a=0.040, mu=0.3, N=1.0e5):
    k_y = 2 * Ky + W * lam / b
    c_psi, k_psi, k_psiy = 2 * f11 * b**2 / V, 2 * Kx * b**2 - W * b * lam, 2 * f11 * b * lam / r0
    F_sat = mu * N

    def rhs(t, x):
        y, p, dy, dp = x
        creep = F_sat * np.tanh(2 * f22 * (dy / V - p) / F_sat)  # the smooth law itself
        ddy = (-creep - k_y * y - flange(y) + k_y * a * np.sin(2 * np.pi * f * t)) / m
        ddp = (-c_psi * dp - k_psi * p - k_psiy * y) / I
        return np.array([dy, dp, ddy, ddp])

    return rhs


def test_wheelset_with_saturating_creep_matches_the_smooth_law_solved_by_scipy():
    system = load_model("wheelset_creep").system()
    (fit,) = system.nonlinear[0].fits
    assert fit.max_error <= 0.01 * 0.3 * 1.0e5
    ours = solve(system, (0, 2.0))
    theirs = reference(creep_rhs(), 4, 2.0)
    t = np.linspace(0, 2.0, 4001)
    x_ours, x_theirs = ours.sol(t), theirs.sol(t)
    # the fitted curve is within 1 % of F_sat of the law: the trajectories differ by that much
    # force acting through the whole run, measured here (not by the same fit)
    for k, state in enumerate(system.states):
        assert nrmsd_percent(x_ours[k], x_theirs[k]) < 0.1, state  # measured 0.024-0.066
    # the saturation matters: with the linear creep law the response is another one
    linear = load_model("wheelset_creep").system(nonlinear={"creep": False})
    x_linear = solve(linear, (0, 2.0)).sol(t)
    assert nrmsd_percent(x_linear[0], x_theirs[0]) > 5


@pytest.mark.parametrize("name", ["bogie", "wheelset_creep"])
def test_shipped_models_critical_speeds(name):
    speed, frequency = critical_speed(load_model(name), None)
    # wheelset_creep's linear part is MODEL.md's derived set (55.626 m/s, 8.470 Hz)
    expected = {"wheelset_creep": (55.626, 8.470), "bogie": (67.161, 5.251)}[name]
    assert (speed, frequency) == pytest.approx(expected, abs=1.5e-3)


def quarter_car_reference(v=10.0, t_stop=3.0, progressive=True):
    ms, mu, ks, cs, kt, d0 = 400.0, 40.0, 2.0e4, 1.5e3, 2.0e5, 0.1
    cubic = ks / d0**2 if progressive else 0.0
    gap_c, gap_r, k_bs, k_rb = 0.04, 0.06, 10 * ks, 5 * ks
    # the road of the file: distance (m), elevation (mm); run over at v
    road = np.array([[0, 0], [5, 0], [6, 60], [9, 60], [10, 0], [20, 0], [20.5, -40],
                     [21.5, -40], [22, 0], [40, 0]], dtype=float)  # fmt: skip
    times, heights = road[:, 0] / v, road[:, 1] / 1000

    def bump_stops(d):  # compression below -gap_c, rebound above gap_r
        return k_bs * np.minimum(d + gap_c, 0) + k_rb * np.maximum(d - gap_r, 0)

    def rhs(t, x):
        zs, zu, vs, vu = x
        d = zs - zu
        suspension = cs * (vs - vu) + ks * d + cubic * d**3 + bump_stops(d)  # smooth
        zr = np.interp(t, times, heights)
        return np.array([vs, vu, -suspension / ms, (suspension - kt * (zu - zr)) / mu])

    # one solve_ivp per stretch between the road's corners (a step across one loses order)
    edges = [0.0, *[c for c in times if 0 < c < t_stop], t_stop]
    x0, pieces = np.zeros(4), []
    for start, stop in zip(edges[:-1], edges[1:], strict=True):
        piece = solve_ivp(rhs, (start, stop), x0, method="DOP853", rtol=1e-11, atol=1e-13,
                          max_step=5e-4, dense_output=True)  # fmt: skip
        pieces.append((start, stop, piece.sol))
        x0 = piece.y[:, -1]

    def sol(t):
        return np.column_stack([next(s for a, b, s in pieces if a <= ti <= b)(ti) for ti in t])

    return sol


def test_quarter_car_matches_its_equations_solved_by_scipy():
    system = load_model("quarter_car").system()
    ours = solve(system, (0, 3.0))
    t = np.linspace(0, 3.0, 3001)
    x_ours, x_theirs = ours.sol(t), quarter_car_reference()(t)
    # the progression is fitted within 0.5 % of ks d0 (10 N): that much force, all through
    for k, state in enumerate(system.states):
        assert nrmsd_percent(x_ours[k], x_theirs[k]) < 0.2, state  # measured 0.029-0.101
    deflection = x_theirs[0] - x_theirs[1]
    assert deflection.min() < -0.04 and deflection.max() > 0.06  # both stops are struck
    # without the progression nothing is fitted: the rest of the equations agree exactly
    linear_spring = load_model("quarter_car").system(nonlinear={"progression": False})
    x_ours = solve(linear_spring, (0, 3.0)).sol(t)
    x_theirs = quarter_car_reference(progressive=False)(t)
    for k, state in enumerate(system.states):
        assert nrmsd_percent(x_ours[k], x_theirs[k]) < 1e-5, state
