"""The full vehicle in the runtime (dampnet._core.FullCar): with its four corners decoupled it
is four quarter cars (the Loop, an independently written integrator of the same equations);
its parameters, arguments and threading contract are guarded like the Loop's."""

import subprocess
import sys
import threading

import numpy as np
import pytest

from dampnet import _core
from dampnet.modeldir import default_model
from dampnet.sim.quarter_car.loop import damper_from_model

DT = 1e-3
M_S_CORNER = 700.0  # the quarter car's sprung mass (thesis Table 5)


def _road(n: int):
    """A road with content up to ~12 Hz (body and wheel hop both excited) [m], [m/s]."""
    t = np.arange(n) * DT
    w = 2 * np.pi * np.array([1.1, 3.7, 11.0])
    amp = np.array([0.02, 0.006, 0.002])
    z = (amp * np.sin(np.outer(t, w))).sum(axis=1)
    v = (amp * w * np.cos(np.outer(t, w))).sum(axis=1)
    return z, v


def _dampers():
    neural = lambda: damper_from_model(default_model())  # noqa: E731  (velocity, acceleration, voltage)
    table = lambda: _core.Damper.table([-1.0, -0.2, 0.0, 0.2, 1.0], [0.0, 5.0],  # noqa: E731
                                       [[-3000, -900, 0, 1000, 3500], [-800, -300, 0, 400, 1200]])
    return {"linear": lambda: _core.Damper.linear(2500.0), "table": table, "neural": neural}


CASES = [(damper, accel, law, evaluation)
         for damper in ("linear", "table", "neural")
         for accel in (("explicit", "linear") if damper == "neural" else ("explicit",))
         for law in ("passive", "skyhook_onoff")
         for evaluation in ("per_stage", "per_step")]


@pytest.mark.parametrize("damper,accel,law,evaluation", CASES)
def test_decoupled_corners_equal_the_quarter_car(damper, accel, law, evaluation):
    """A symmetric car (a == b, t_f == t_r, m_s = 4 x the quarter car's, pitch and roll inertia
    matched, no anti-roll bars, at rest) on the same road at all four wheels moves as four quarter cars: each corner equals
    the quarter-car Loop to 1e-9 (relative to the motion's size) in displacement, force and
    control. The body's pitch and roll stay 0."""
    n = 2500
    z, v = _road(n)
    make = _dampers()[damper]
    controller = {"kind": law, "u_passive": 1.0}
    # inertias matched: the body's mobility at a corner, 1/m_s + a^2/i_yy + (t/2)^2/i_xx, is the
    # quarter car's 1/700 kg, so the coupled acceleration scheme sees the quarter car's mass
    m_s = 4 * M_S_CORNER
    params = dict(m_s=m_s, i_yy=1.5**2 * m_s / 1.5, i_xx=0.8**2 * m_s / 1.5,
                  a=1.5, b=1.5, t_f=1.6, t_r=1.6, k_arb_f=0.0, k_arb_r=0.0,
                  m_us_f=40.0, m_us_r=40.0, k_s_f=15000.0, k_s_r=15000.0, k_t=2e5, c_t=0.0,
                  speed=0.0, dt=DT, damper_eval=evaluation, accel_feature=accel)
    car = _core.FullCar(_core.FullCarModel([make() for _ in range(4)], params, controller))
    full = car.simulate(np.repeat(z[:, None], 4, axis=1), np.repeat(v[:, None], 4, axis=1))
    vehicle = dict(m_s=M_S_CORNER, m_us=40.0, k_s=15000.0, k_t=2e5, c_t=0.0, dt=DT,
                   damper_eval=evaluation, accel_feature=accel)
    quarter = _core.Loop(_core.LoopModel(make(), vehicle, controller)).simulate(z, v)
    names, qnames = _core.FULLCAR_STATE_NAMES, _core.STATE_NAMES
    S, Q = full["state"], quarter["state"]
    scale_z = np.max(np.abs(Q[:, qnames.index("z_s")]))
    scale_f = np.max(np.abs(quarter["force"]))
    assert scale_z > 5e-3 and scale_f > 50.0  # the road moves the car (else nothing is compared)
    # pitch and roll stay 0 (to rounding: the coupled 4x4 solve of accel "linear" pivots)
    assert np.max(np.abs(S[:, names.index("phi")])) <= 1e-12
    assert np.max(np.abs(S[:, names.index("theta")])) <= 1e-12
    for c, corner in enumerate(_core.FULLCAR_CORNERS):
        np.testing.assert_allclose(S[:, names.index("z")], Q[:, qnames.index("z_s")], rtol=0,
                                   atol=1e-9 * scale_z)
        np.testing.assert_allclose(S[:, names.index(f"z_us_{corner}")], Q[:, qnames.index("z_us")],
                                   rtol=0, atol=1e-9 * scale_z)
        np.testing.assert_allclose(full["force"][:, c], quarter["force"], rtol=0, atol=1e-9 * scale_f)
        np.testing.assert_allclose(full["u"][:, c], quarter["control"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(full["a"][:, c], quarter["a"], rtol=0,
                                   atol=1e-9 * np.max(np.abs(quarter["a"])))


def test_corner_mobility_is_the_rigid_body_one():
    """K (FullCarModel.corner_mobility) against the body's mass matrix inverted by numpy: the
    corners' vertical accelerations per unit upward force, plus the wheel's 1/m_us."""
    model = _core.FullCarModel([_core.Damper.linear(0.0)] * 4)
    p = model.params
    x = np.array([p["a"], p["a"], -p["b"], -p["b"]])
    y = np.array([p["t_f"], -p["t_f"], p["t_r"], -p["t_r"]]) / 2
    J = np.stack([np.ones(4), y, -x], axis=1)  # corner height per (z, phi, theta)
    M = np.diag([p["m_s"], p["i_xx"], p["i_yy"]])
    G = J @ np.linalg.inv(M) @ J.T
    m_us = np.array([p["m_us_f"], p["m_us_f"], p["m_us_r"], p["m_us_r"]])
    np.testing.assert_allclose(model.corner_mobility, G + np.diag(1 / m_us), rtol=1e-13)


def test_steady_turn_is_plausible_and_loads_transfer_outward():
    """A 0.03 rad step steer at 120 km/h with the defaults: a left turn (a_y > 0, r > 0), the
    body rolls outward (phi > 0: left side up), the right (outside) tyres carry more load, the
    total load stays the car's weight, and the yaw rate is below the neutral-steer value U/L
    delta (the defaults understeer)."""
    model = _core.FullCarModel([_core.Damper.linear(3000.0)] * 4, {"dt": 2e-3})
    p = model.params
    n = 2500
    res = _core.FullCar(model).simulate(np.zeros((n, 4)), np.zeros((n, 4)), steer=np.full(n, 0.03))
    S, names = res["state"], _core.FULLCAR_STATE_NAMES
    r, phi = S[-1, names.index("r")], S[-1, names.index("phi")]
    assert res["a_y"][-1] > 2.0 and r > 0 and phi > 0
    loads = res["tyre_load"][-1]
    assert loads[1] > loads[0] and loads[3] > loads[2]
    weight = p["g"] * (p["m_s"] + 2 * p["m_us_f"] + 2 * p["m_us_r"])
    np.testing.assert_allclose(loads.sum(), weight, rtol=1e-3)
    assert r < p["speed"] / (p["a"] + p["b"]) * 0.03
    np.testing.assert_allclose(res["a_y"][-1], p["speed"] * r, rtol=1e-3)  # steady: a_y = U r


def test_check_fullcar_names_the_field():
    _core.check_fullcar({})
    with pytest.raises(ValueError, match=r"'i_xx' = -1.0 \(sprung-mass roll inertia.*\[kg m\^2\]"):
        _core.check_fullcar({"i_xx": -1.0})
    with pytest.raises(ValueError, match=r"'h_rc_r'.*h_rc_r < h_cg"):
        _core.check_fullcar({"h_rc_r": 2.0})
    with pytest.raises(ValueError, match=r"'tyre_model': unknown name 'pacejka'.*'magic_formula' \(0\)"):
        _core.check_fullcar({"tyre_model": "pacejka"})
    with pytest.raises(ValueError, match=r"unknown parameter 'mass'; known: m_s i_xx"):
        _core.check_fullcar({"mass": 1.0})
    with pytest.raises(TypeError, match=r"'speed'.*expected a number"):
        _core.check_fullcar({"speed": "fast"})


def test_bad_arguments_are_clear_errors():
    lin = _core.Damper.linear(1000.0)
    with pytest.raises(ValueError, match=r"4 Dampers \(FL, FR, RL, RR\), got 3"):
        _core.FullCarModel([lin] * 3)
    with pytest.raises(TypeError, match=r"dampers\[2\] \(rl\) must be a Damper"):
        _core.FullCarModel([lin, lin, None, lin])
    with pytest.raises(ValueError, match=r"controllers\[1\].*'u_min'"):
        _core.FullCarModel([lin] * 4, {}, [{}, {"u_min": 9.0}, {}, {}])
    with pytest.raises(ValueError, match=r"steer_mode 'driver' needs a path"):
        _core.FullCarModel([lin] * 4, {"steer_mode": "driver"})
    with pytest.raises(ValueError, match=r"strictly increasing \(point 2\)"):
        _core.FullCarModel([lin] * 4, {"steer_mode": "driver"}, None, [0.0, 1.0, 1.0], [0.0, 0.0, 0.0])
    car = _core.FullCar(_core.FullCarModel([lin] * 4))
    with pytest.raises(ValueError, match=r"\[n, 4\]"):
        car.simulate(np.zeros((10, 3)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match=r"steer \[rad\] must be 1-D with one value per road row"):
        car.simulate(np.zeros((10, 4)), np.zeros((10, 4)), steer=np.zeros(9))
    with pytest.raises(ValueError, match=r"expected 4 values"):
        car.step([0.0, 0.0], [0.0] * 4)
    before = car.state
    with pytest.raises(ValueError, match=r"DN_E_NONFINITE_INPUT|NaN or infinite"):
        car.step([0.0, np.nan, 0.0, 0.0], [0.0] * 4)
    np.testing.assert_array_equal(car.state, before)
    with pytest.raises(ValueError, match=r"53 values"):
        car.state = np.zeros(13)


def test_hostile_calls_do_not_crash_the_interpreter():
    """Every call below raises (or returns) in a child interpreter that must exit cleanly."""
    code = r"""
import numpy as np
from dampnet import _core
lin = _core.Damper.linear(1.0)
calls = [
    lambda: _core.FullCar(None),
    lambda: _core.FullCar.__new__(_core.FullCar).step([0]*4, [0]*4),
    lambda: _core.FullCarModel.__new__(_core.FullCarModel).params,
    lambda: _core.FullCarModel("abcd"),
    lambda: _core.FullCarModel([lin]*4, {"dt": float("nan")}),
    lambda: _core.FullCarModel([lin]*4, {"dt": 1e-320}),
    lambda: _core.FullCarModel([lin]*4, {}, 5),
    lambda: _core.FullCarModel([lin]*4, {}, None, np.zeros(10**4), np.zeros(10**4)),
    lambda: _core.FullCarModel([lin]*4, {}, None, "xy", "xy"),
    lambda: _core.FullCar(_core.FullCarModel([lin]*4)).simulate(np.zeros((0, 4)), np.zeros((0, 4))),
    lambda: _core.FullCar(_core.FullCarModel([lin]*4)).simulate("road", None),
    lambda: _core.FullCar(_core.FullCarModel([lin]*4)).simulate(np.full((5, 4), 1e308), np.full((5, 4), -1e308)),
    lambda: _core.FullCar(_core.FullCarModel([lin]*4)).step([1e308]*4, [1e308]*4, 1e308),
    lambda: _core.FullCar(_core.FullCarModel([lin]*4, {}, {"kind": "external"})).step([0]*4, [0]*4, 0.0, [np.nan]*4),
]
for c in calls:
    try:
        c()
    except (ValueError, TypeError, RuntimeError):
        pass
print("survived", len(calls))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "survived 14" in out.stdout


def test_a_fullcar_refuses_concurrent_use():
    """simulate releases the GIL: a second call on the same FullCar meanwhile is refused with
    RuntimeError naming the contract, and the first run's result is untouched."""
    car = _core.FullCar(_core.FullCarModel([_core.Damper.linear(2500.0)] * 4))
    n = 400_000
    z = np.zeros((n, 4))
    results, errors = [], []
    started = threading.Event()

    def run():
        started.set()
        results.append(car.simulate(z, z))

    th = threading.Thread(target=run)
    th.start()
    started.wait()
    while th.is_alive():
        try:
            car.step([0.0] * 4, [0.0] * 4)
        except RuntimeError as e:
            errors.append(str(e))
            break
    th.join()
    assert errors and "one mutable vehicle state" in errors[0]
    assert np.all(results[0]["status"] >= 0) and np.all(results[0]["state"][:, 1] == 0.0)


@pytest.mark.parametrize("evaluation", ["per_step", "per_stage"])
def test_corners_sharing_one_damper_evaluate_in_one_pass_with_identical_results(evaluation):
    """Four corners given one float neural damper object go through the kernel together
    (Damper::force_da4); four objects of the same model go one call each. The runs are
    bit-identical (and the batch was taken: the evaluation count is the same, the path is
    checked in C++ by tests/cpp/unit/test_mlp_batch.cpp)."""
    model = default_model()
    n = 1500
    z, v = _road(n)
    road = np.stack([z, 0.8 * z, np.roll(z, 50), np.roll(z, 70)], axis=1)
    rate = np.stack([v, 0.8 * v, np.roll(v, 50), np.roll(v, 70)], axis=1)
    steer = 0.03 * np.sin(np.arange(n) * DT * 3.0)
    params = {"damper_eval": evaluation, "accel_feature": "linear"}
    shared = damper_from_model(model, single=True)
    runs = []
    for dampers in ([shared] * 4, [damper_from_model(model, single=True) for _ in range(4)]):
        car = _core.FullCar(_core.FullCarModel(dampers, params, {"kind": "skyhook_onoff"}))
        runs.append((car.simulate(road, rate, steer=steer), car.damper_evals))
    (a, na), (b, nb) = runs
    assert na == nb
    for key in ("state", "force", "a", "status"):
        np.testing.assert_array_equal(a[key], b[key])
    assert np.max(np.abs(a["force"])) > 100.0
