"""The full vehicle's preview driver (fullcar.hpp, steer_mode driver) against independent
references: a straight line (the path's offset reached, no steering left), a steady circle (the
steady steer and yaw rate of the linear bicycle model, dampnet.sim.full_car.linear.bicycle), the
ISO 3888-1 lane change at 80 km/h (passed: no cone, by the footprint's clearance), the --max-speed
bisection (its bracket re-run), and the bounce sweep's transmissibility against the linear
model's frequency response."""

import numpy as np
import pytest

from cbuild import ROOT
from dampnet import _core
from dampnet.recipes import maneuvers as recipes
from dampnet.sim.dampers import load_spec
from dampnet.sim.full_car import linear
from dampnet.sim.full_car.metrics import bsst_response

NAMES = _core.FULLCAR_STATE_NAMES
MODEL = str(ROOT / "export" / "dn_model_default.json")   # the repository's, wherever pytest runs


def _drive(params: dict, px, py, seconds: float) -> dict:
    dt = params["dt"]
    n = int(round(seconds / dt))
    model = _core.FullCarModel([_core.Damper.linear(3000.0)] * 4, {**params, "steer_mode": "driver"}, None,
                               np.asarray(px, float), np.asarray(py, float))
    return _core.FullCar(model).simulate(np.zeros((n, 4)), np.zeros((n, 4)))


def _col(res, name):
    return res["state"][:, NAMES.index(name)]


@pytest.mark.parametrize("speed", [10.0, 30.0])
def test_driver_settles_on_a_straight_line(speed):
    """A straight path 0.5 m left of the start: the car ends on it (1 mm) heading along it, with
    no steering left; on a path through the start it never steers at all."""
    params = {"speed": speed, "dt": 1e-3}
    res = _drive(params, [-10.0, 1000.0], [0.5, 0.5], 8.0)
    assert abs(_col(res, "y_pos")[-1] - 0.5) < 1e-3
    assert abs(_col(res, "psi")[-1]) < 1e-4 and abs(res["steer"][-1]) < 1e-4
    assert np.max(np.abs(np.diff(res["steer"]))) <= params["dt"] * _core.FULLCAR_FIELDS["driver_rate_max"][0] + 1e-12
    res0 = _drive(params, [-10.0, 1000.0], [0.0, 0.0], 2.0)
    assert np.max(np.abs(res0["steer"])) == 0.0 and np.max(np.abs(_col(res0, "y_pos"))) == 0.0


def test_driver_on_a_steady_circle_steers_as_the_bicycle_model():
    """An arc of radius 150 m at 20 m/s (a_y 2.7 m/s^2), linear tyres, no steering lag: once
    steady, the road-wheel angle is the bicycle model's L / R + K a_y and the yaw rate U / R,
    both to 1 %, and the car stays within 2 cm of the arc."""
    R, U = 150.0, 20.0
    params = {"speed": U, "dt": 1e-3, "tyre_model": "linear", "driver_tau_s": 0.0}
    x = np.r_[-20.0, np.linspace(0.0, R * np.sin(np.radians(50)), 200)]
    y = np.where(x > 0, R - np.sqrt(np.maximum(R**2 - x**2, 0.0)), 0.0)
    res = _drive(params, x, y, 5.5)
    ref = linear.bicycle(params)
    L = linear.full_params(params)["a"] + linear.full_params(params)["b"]
    X, Y = _col(res, "x_pos"), _col(res, "y_pos")
    steady = (X > 40.0) & (X < 100.0)
    assert steady.sum() > 2000
    delta = res["steer"][steady]
    np.testing.assert_allclose(np.mean(delta), L / R + ref["understeer_gradient"] * U**2 / R, rtol=1e-2)
    np.testing.assert_allclose(np.mean(_col(res, "r")[steady]), U / R, rtol=1e-2)
    radial = np.hypot(X[steady], Y[steady] - R) - R
    assert np.max(np.abs(radial)) < 0.02


@pytest.mark.parametrize("damping", ["low", "high", "skyhook"])
def test_lane_change_at_80_kmh_is_passed(damping):
    """ISO 3888-1 at 80 km/h with the default neural damper: no cone hit, the footprint at least
    3 cm from every cone, the peak lateral acceleration within 25 % of the path's (U^2 kappa_max),
    and the car settled within 3 s after the exit gate."""
    man = recipes.build("dlc", 1e-3, {"speed_kmh": 80.0})
    m = recipes.run(load_spec(MODEL), man, damping)["metrics"]
    assert m["passed"] and m["cones_hit"] == 0
    assert m["clearance_min_m"] > 0.03
    assert man.meta["path_a_y_peak_m_s2"] < m["a_y_peak_m_s2"] < 1.25 * man.meta["path_a_y_peak_m_s2"]
    assert m["settle_after_exit_s"] < 3.0


def test_max_speed_bisection_brackets_the_pass_fail_edge():
    """--max-speed at 120 km/h: the highest passing speed found passes and the bracket's other end
    fails when run again on its own, 0.5 km/h apart."""
    spec = load_spec("linear:2500")
    man = recipes.build("dlc", 2e-3, {"speed_kmh": 120.0, "max_speed": True})
    res = recipes.run(spec, man, "high")
    m = res["metrics"]
    lo, hi = m["max_speed_kmh"], m["max_speed_fails_kmh"]
    assert 0 < hi - lo <= recipes.MAX_SPEED_TOL_KMH
    assert [120.0, False] == res["max_speed_runs"][0][:2]   # the run itself is the first try
    for kmh, passes in ((lo, True), (hi, False)):
        again = recipes.run(spec, recipes.build("dlc", 2e-3, {"speed_kmh": kmh}), "high")["metrics"]
        assert again["passed"] is passes, kmh


@pytest.mark.parametrize("mode", ["heave", "pitch"])
def test_bsst_transmissibility_equals_the_linear_model(mode):
    """Linear dampers: the sweep's transmissibility estimate (body heave or pitch, and the wheels)
    equals the linear model's frequency response to 1 % over 0.5-20 Hz (measured: 2e-4, dampers
    evaluated per stage), and the peaks it reports lie within 0.1 Hz of the linear model's."""
    c = 1500.0   # [N s/m]: about the default neural damper's equivalent at low damping (1670)
    man = recipes.build("bsst", 1e-3, {"mode": mode})
    r = recipes.run(load_spec(f"linear:{c}"), man, "low")
    resp = bsst_response(r["arrays"], man, r["params"])
    H = linear.road_response(resp["f_hz"], r["params"], c, mode)
    np.testing.assert_allclose(np.abs(resp["body"]), np.abs(H["z" if mode == "heave" else "theta"]), rtol=1e-2)
    np.testing.assert_allclose(np.abs(resp["wheel"]), np.abs(H["wheel"]), rtol=1e-2)
    m = r["metrics"]
    for key in ("body", "wheel_hop"):
        assert abs(m[f"{key}_peak_hz"] - m[f"{key}_peak_hz_linear"]) < 0.1, key
        np.testing.assert_allclose(m[f"{key}_equivalent_damping_n_s_m"], c, rtol=1e-9)
    if mode == "heave":   # the damped heave and wheel-hop peaks, below the modes 0.73 and 11.7 Hz
        assert 0.6 < m["body_peak_hz"] < 0.8 and 10.0 < m["wheel_hop_peak_hz"] < 12.0
