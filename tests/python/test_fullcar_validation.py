"""The runtime's full vehicle (dampnet._core.FullCar) against independent references:
the linear model's matrices (dampnet.sim.full_car.linear, derived from energies) with scipy.linalg for
the modes and frequency responses, the linear bicycle model and the analytic roll gradient for
steady cornering, and energy conservation of the undamped car under RK4."""

import numpy as np
import pytest
import scipy.linalg

from dampnet import _core
from dampnet.sim.full_car import linear

NAMES = _core.FULLCAR_STATE_NAMES
Q_IDX = [NAMES.index(n) for n in linear.COORDINATES]
QD_IDX = [NAMES.index(n) for n in ("vz", "p", "q", "v_us_fl", "v_us_fr", "v_us_rl", "v_us_rr")]
DAMPING = 2500.0  # [N s/m] per corner: the linear dampers of the linear checks


def _car(params: dict, damping: float = DAMPING) -> _core.FullCar:
    return _core.FullCar(_core.FullCarModel([_core.Damper.linear(damping)] * 4, params))


def _step_map(car: _core.FullCar, dt: float) -> np.ndarray:
    """The Jacobian of one runtime step with respect to [q, q'] at rest (the system is linear
    there, so central differences are exact to rounding)."""
    idx = Q_IDX + QD_IDX
    Phi = np.zeros((14, 14))
    for j, col in enumerate(idx):
        cols = []
        for sign in (1.0, -1.0):
            car.reset()
            s = car.state
            s[col] = sign * 1e-6
            car.state = s
            car.step(np.zeros(4), np.zeros(4))
            cols.append(car.state[idx])
        Phi[:, j] = (cols[0] - cols[1]) / 2e-6
    return Phi


def test_modes_equal_the_eigenvalues_of_the_matrices():
    """Linear dampers and tyres, speed 0: the seven modes (heave, pitch, roll, four wheel hops)
    of the runtime's step map, lambda = log(mu) / dt, equal scipy.linalg.eig of the
    state-space matrix built from M, C, K, to 0.5 % in frequency and damping ratio (RK4 at
    dt = 1 ms is within ~1e-6 of the exact flow for these modes)."""
    dt = 1e-3
    params = {"speed": 0.0, "dt": dt, "c_t": 150.0}
    mu = np.linalg.eigvals(_step_map(_car(params), dt))
    lam_rt = np.log(mu.astype(complex)) / dt
    lam_rt = lam_rt[lam_rt.imag > 0]
    lam_rt = lam_rt[np.argsort(np.abs(lam_rt))]
    A, _ = linear.vertical_model(params, DAMPING).state_space()
    lam = scipy.linalg.eig(A, right=False)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]
    assert len(lam) == len(lam_rt) == 7
    f_rt, f = np.abs(lam_rt) / (2 * np.pi), np.abs(lam) / (2 * np.pi)
    z_rt, z = -lam_rt.real / np.abs(lam_rt), -lam.real / np.abs(lam)
    np.testing.assert_allclose(f_rt, f, rtol=5e-3)
    np.testing.assert_allclose(z_rt, z, rtol=5e-3)
    # sanity: body modes near 1-1.5 Hz, wheel hops near 11-13 Hz (the Table 5 corner)
    assert 0.5 < f[0] < 2.0 and 9.0 < f[-1] < 15.0


PATTERNS = {  # road amplitude per wheel FL, FR, RL, RR [m] and the output they excite
    "heave": (np.array([1.0, 1.0, 1.0, 1.0]), "z"),
    "pitch": (np.array([1.0, 1.0, -1.0, -1.0]), "theta"),
    "roll": (np.array([1.0, -1.0, 1.0, -1.0]), "phi"),
}


@pytest.mark.parametrize("pattern", list(PATTERNS))
def test_frequency_response_equals_the_state_space_model(pattern):
    """Body heave / pitch / roll per road amplitude from the runtime's time simulation (a sine
    at each frequency, the steady cycle fitted by least squares) against the frequency
    response of the linear state space, 0.5-20 Hz, to 0.5 % in gain and 0.005 rad
    in phase."""
    dt = 5e-4
    params = {"speed": 0.0, "dt": dt, "c_t": 0.0}
    car = _car(params)
    A, B = linear.vertical_model(params, DAMPING).state_space()
    amp, output = PATTERNS[pattern]
    k = linear.COORDINATES.index(output)
    Cout = np.zeros((1, 14))
    Cout[0, k] = 1.0
    # H(jw) = C (jw I - A)^-1 B by a complex solve (scipy.signal.freqresp would convert this
    # 14-state system to a transfer-function polynomial, badly conditioned: BadCoefficients)
    freqs = np.array([0.5, 1.0, 1.5, 2.5, 4.0, 7.0, 11.0, 15.0, 20.0])
    H = [(Cout @ scipy.linalg.solve(2j * np.pi * f * np.eye(14) - A, B @ amp))[0] for f in freqs]
    a0 = 0.005  # [m]
    for f, h in zip(freqs, H):
        w = 2 * np.pi * f
        settle = 8.0  # [s]: the slowest body mode (~1 Hz, zeta ~0.2) decays by e^-10
        n_cyc = max(3, int(round(2.0 * f)))
        n = int(round((settle + n_cyc / f) / dt)) + 1
        t = np.arange(n) * dt
        road = a0 * np.sin(w * t)[:, None] * amp
        rate = a0 * w * np.cos(w * t)[:, None] * amp
        y = car.simulate(road, rate)["state"][:, Q_IDX[k]]
        tail = t >= settle
        X = np.stack([np.sin(w * t[tail]), np.cos(w * t[tail])], axis=1)
        (s_coef, c_coef), *_ = np.linalg.lstsq(X, y[tail], rcond=None)
        resp = complex(s_coef, c_coef) / a0  # y = Im(H e^{iwt}) = |H| sin(wt + arg H)
        np.testing.assert_allclose(abs(resp), abs(h), rtol=5e-3, err_msg=f"{pattern} {f} Hz gain")
        assert abs(np.angle(resp / h)) < 5e-3, (pattern, f, np.angle(resp), np.angle(h))


def _steady_turn(params: dict, steer: float, seconds: float = 8.0):
    dt = params["dt"]
    n = int(seconds / dt)
    res = _car(params, 4000.0).simulate(np.zeros((n, 4)), np.zeros((n, 4)), steer=np.full(n, steer))
    return res, res["state"][-1]


def test_steady_cornering_equals_the_bicycle_model_and_the_roll_gradient():
    """Linear tyres (the static loads' cornering stiffness), a small constant steer at 20 m/s:
    yaw-rate gain r / delta and the understeer gradient K (delta = L/R + K a_y) equal the
    linear bicycle model's; the body's roll per lateral acceleration equals the analytic roll
    gradient from the axles' roll stiffnesses (springs and bars in series with the tyres) and
    the roll-centre heights; all to 1 %."""
    params = {"speed": 20.0, "dt": 2e-3, "tyre_model": "linear", "driver_tau_s": 0.0}
    ref = linear.bicycle(params)
    L = params_L = linear.full_params(params)["a"] + linear.full_params(params)["b"]
    delta = 0.01  # [rad]
    res, s = _steady_turn(params, delta)
    r = s[NAMES.index("r")]
    a_y = res["a_y"][-1]
    assert abs(res["a_y"][-1] - res["a_y"][-200]) < 1e-6 * abs(a_y)  # steady
    np.testing.assert_allclose(r / delta, ref["yaw_rate_gain"], rtol=1e-2)
    K = (delta - L * r / params["speed"]) / a_y
    np.testing.assert_allclose(K, ref["understeer_gradient"], rtol=1e-2)
    assert ref["understeer_gradient"] > 0 and params_L > 0  # the defaults understeer
    np.testing.assert_allclose(s[NAMES.index("phi")] / a_y, linear.roll_gradient(params), rtol=1e-2)


def test_roll_gradient_follows_the_roll_centres_and_bars():
    """The analytic roll gradient's dependence is the runtime's too: raising the roll centres
    and stiffening the bars lowers the roll per a_y as the closed form says (1 %)."""
    for change in ({"h_rc_f": 0.3, "h_rc_r": 0.5}, {"k_arb_f": 80000.0, "k_arb_r": 40000.0}):
        params = {"speed": 20.0, "dt": 2e-3, "tyre_model": "linear", "driver_tau_s": 0.0, **change}
        res, s = _steady_turn(params, 0.01)
        np.testing.assert_allclose(s[NAMES.index("phi")] / res["a_y"][-1], linear.roll_gradient(params),
                                   rtol=1e-2)
    base = linear.roll_gradient({})
    assert linear.roll_gradient({"h_rc_f": 0.3, "h_rc_r": 0.5}) < base
    assert linear.roll_gradient({"k_arb_f": 80000.0, "k_arb_r": 40000.0}) < base


def _energy_drift(dt: float, seconds: float = 60.0) -> tuple[float, float]:
    params = {"speed": 0.0, "dt": dt, "c_t": 0.0}
    car = _car(params, 0.0)
    model = linear.vertical_model(params, 0.0)
    car.reset()
    s = car.state
    s[NAMES.index("z")] = 0.03
    s[NAMES.index("phi")] = 0.02
    s[NAMES.index("theta")] = -0.01
    s[NAMES.index("z_us_fl")] = 0.01
    car.state = s
    n = int(seconds / dt)
    S = car.simulate(np.zeros((n, 4)), np.zeros((n, 4)), reset=False)["state"]
    E = model.energy(S[:, Q_IDX], S[:, QD_IDX])
    return float(np.max(np.abs(E - E[0]))), float(E[0])


def test_undamped_energy_is_conserved_to_the_order_of_rk4():
    """No damping (linear dampers of 0 N s/m, c_t = 0): the total energy (kinetic, springs,
    bars, tyres, the roll gravity term) drifts over 60 s by a small fraction, and the drift
    falls as RK4's order says when dt halves: per step RK4 scales an undamped mode's energy by
    |R(i w h)|^2 = 1 - (w h)^6 / 72 + ..., so over a fixed time the drift goes as h^5 (a 2^5 =
    32-fold fall; 24..40 accepted)."""
    d1, e0 = _energy_drift(2e-3)
    d2, _ = _energy_drift(1e-3)
    assert e0 > 10.0  # the initial displacement stores energy (else nothing is tested)
    assert d1 / e0 < 1e-3
    assert 24.0 < d1 / d2 < 40.0, (d1, d2)
