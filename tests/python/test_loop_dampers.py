"""Each damper model of the loop against an independent Python implementation of
its formula: linear, parametric (thesis eq. 1-3), lookup table (bilinear, clamped),
neural (numpy MLP on named features), hybrid (terms + MLP), and the term table
(dampnet.terms vs the C++ table)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

from dampnet import _core, terms as T
from dampnet.sim.quarter_car.loop import add_terms, damper_from_model
from loop_helpers import numpy_forward, random_model

rng = np.random.default_rng(42)
N = 2000
X = rng.uniform(-0.12, 0.12, N)
V = rng.uniform(-2.5, 2.5, N)
A = rng.uniform(-250, 250, N)
U = rng.uniform(-0.5, 5.5, N)
UL = rng.uniform(0, 5, N)
TEMP = rng.uniform(-10, 100, N)


def forces(d, x=X, v=V, a=A, u=U, ul=UL, temp=TEMP):
    f, st, mask = d.forces(x, v, a, u, ul, temp)
    return f, st


def test_linear():
    f, st = forces(_core.Damper.linear(1234.5))
    np.testing.assert_allclose(f, 1234.5 * V, rtol=1e-15)
    assert np.all(st == 0)


def parametric_reference(v, u, c_min, c_max, gamma, f0, v_max, v_smooth):
    """Thesis eq. 1-3, written independently."""
    V = np.clip(u, 0.0, v_max)
    with np.errstate(divide="ignore"):
        c = np.where(V != 0, gamma / np.where(V != 0, V, 1.0) + c_min, c_max)
    c = np.clip(c, c_min, c_max)
    sgn = np.tanh(v / v_smooth) if v_smooth > 0 else np.sign(v)
    return c * v + f0 * sgn


@pytest.mark.parametrize("v_smooth", [0.0, 0.02])
def test_parametric_matches_thesis_equations(v_smooth):
    p = dict(c_min=400.0, c_max=3500.0, gamma=1800.0, f0=60.0, v_max=5.0, v_smooth=v_smooth)
    u = np.concatenate([U, [0.0, 0.0, 1e-300, 5.0, 7.0, -1.0]])
    v = np.concatenate([V, [0.0, 0.3, -0.3, 0.3, 0.3, 0.3]])
    n = u.size
    f, st = _core.Damper.parametric(**p).forces(np.zeros(n), v, np.zeros(n), u, np.zeros(n),
                                                np.zeros(n))[:2]
    np.testing.assert_allclose(f, parametric_reference(v, u, **p), rtol=1e-13, atol=1e-12)
    # the documented edges: sgn(0) = 0 (exact), V = 0 is the hardest, V beyond v_max clamps
    if v_smooth == 0:
        assert f[N] == 0.0
    assert f[N + 1] == pytest.approx(3500 * 0.3 + 60)
    assert f[N + 5] == pytest.approx(3500 * 0.3 + 60)  # V < 0 clamps to 0
    assert f[N + 4] == pytest.approx((1800 / 5 + 400) * 0.3 + 60)


@pytest.mark.parametrize("bad", [dict(c_min=-1.0), dict(c_max=100.0), dict(v_max=0.0),
                                 dict(f0=float("nan")), dict(v_smooth=-1.0)])
def test_parametric_refuses_nonsense(bad):
    p = dict(c_min=400.0, c_max=3500.0, gamma=1800.0, f0=60.0, v_max=5.0)
    p.update(bad)
    with pytest.raises(ValueError, match="DN_E_PARAM|DN_E_NONFINITE_PARAM"):
        _core.Damper.parametric(**p)


def make_table():
    vel = np.array([-1.5, -0.5, -0.1, 0.0, 0.1, 0.5, 1.5])
    ctl = np.array([0.0, 1.0, 2.5, 5.0])
    F = (np.array([3000.0, 2000.0, 1200.0, 600.0])[:, None] * np.tanh(vel / 0.4)[None, :]
         + 50 * np.arange(4)[:, None])
    return vel, ctl, F


def test_table_is_bilinear_and_clamped():
    vel, ctl, F = make_table()
    d = _core.Damper.table(vel, ctl, F)
    f, st = forces(d)
    ref = RegularGridInterpolator((ctl, vel), F, method="linear")(
        np.stack([np.clip(U, ctl[0], ctl[-1]), np.clip(V, vel[0], vel[-1])], axis=1))
    np.testing.assert_allclose(f, ref, rtol=1e-12, atol=1e-9)
    outside = (U < ctl[0]) | (U > ctl[-1]) | (V < vel[0]) | (V > vel[-1])
    assert np.all((st == _core.DN_W_SATURATED) == outside)
    # grid points exactly, and a mid point by hand
    gv, gu = np.meshgrid(vel, ctl)
    n = gv.size
    fg = d.forces(np.zeros(n), gv.ravel(), np.zeros(n), gu.ravel(), np.zeros(n), np.zeros(n))[0]
    np.testing.assert_array_equal(fg, F.ravel())
    fm = d.forces([0.0], [0.3], [0.0], [1.75], [0.0], [0.0])[0][0]
    w_v, w_u = (0.3 - 0.1) / 0.4, (1.75 - 1.0) / 1.5
    lo = F[1, 4] + w_v * (F[1, 5] - F[1, 4])
    hi = F[2, 4] + w_v * (F[2, 5] - F[2, 4])
    assert fm == pytest.approx(lo + w_u * (hi - lo), rel=1e-13)


def test_table_with_one_control_ignores_control():
    vel, _, F = make_table()
    d = _core.Damper.table(vel, np.array([2.0]), F[:1])
    f, _ = forces(d)
    np.testing.assert_allclose(f, np.interp(V, vel, F[0]), rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("args, code", [
    ((np.array([0.0, -1.0]), np.array([0.0]), np.zeros((1, 2))), "DN_E_PARAM"),
    ((np.array([0.0]), np.array([0.0]), np.zeros((1, 1))), "DN_E_SIZE"),
    ((np.linspace(-1, 1, 65), np.array([0.0]), np.zeros((1, 65))), "DN_E_SIZE"),
    ((np.array([0.0, 1.0]), np.array([0.0]), np.array([[0.0, np.nan]])), "DN_E_NONFINITE_PARAM"),
])
def test_table_refuses_nonsense(args, code):
    with pytest.raises(ValueError, match=code):
        _core.Damper.table(*args)


ALL = ["velocity", "acceleration", "displacement", "voltage", "voltage_lag", "temperature"]
COLS = {"velocity": V, "acceleration": A, "displacement": X, "voltage": U, "current": U,
        "voltage_lag": UL, "current_lag": UL, "temperature": TEMP}


@pytest.mark.parametrize("features", [["velocity", "acceleration", "voltage"], ALL,
                                      ["current", "velocity", "current_lag"]])
def test_neural_reads_features_by_name(features):
    m = random_model(features, seed=len(features), feature_params={"control_lag_tau_s": 0.03})
    f, st = forces(damper_from_model(m))
    ref = numpy_forward(m, np.stack([COLS[n] for n in features], axis=1))
    np.testing.assert_allclose(f, ref, rtol=1e-12, atol=1e-9)
    ff, _ = forces(damper_from_model(m, single=True))
    assert np.max(np.abs(ff - ref)) < 1e-4 * 4000


def test_neural_unknown_feature_or_param_fails_at_creation():
    m = random_model(["velocity", "acceleration"])
    m.features = ["velocity", "jerk"]
    with pytest.raises(ValueError, match="unknown feature.*known features: velocity"):
        damper_from_model(m)
    m = random_model(["velocity"], feature_params={"spin_rate": 1.0})
    with pytest.raises(ValueError, match="UNKNOWN_NAME"):
        damper_from_model(m)
    m = random_model(["velocity", "voltage_lag"])  # a lag without its time constant
    with pytest.raises(ValueError, match="DN_E_PARAM"):
        damper_from_model(m)
    m = random_model(["velocity", "voltage_lag"])
    m.feature_params = {"control_lag_tau_s": 0.0}  # after construction: MlpModel.validate refuses it too
    with pytest.raises(ValueError, match="DN_E_PARAM"):
        damper_from_model(m)


def test_neural_nonfinite_input_is_refused():
    d = damper_from_model(random_model(["velocity", "acceleration"]))
    f, st, _ = d.forces([0.0], [np.nan], [0.0], [0.0], [0.0], [0.0])
    assert st[0] == _core.DN_E_NONFINITE_INPUT and f[0] == 0.0


TERMS = [{"kind": "position_poly", "params": [-180.0, 2500.0, 1.5e4, 8e5]},
         {"kind": "bump_stop", "params": [0.06, 3e6, 1.7]}]


def term_reference(x):
    """The two terms, written out independently of dampnet.terms."""
    p = TERMS[0]["params"]
    poly = p[0] + p[1] * x + p[2] * x ** 2 + p[3] * x ** 3
    xf, k, n = TERMS[1]["params"]
    bump = np.where(x > xf, k * np.abs(x - xf) ** n, 0.0) - np.where(x < -xf, k * np.abs(-x - xf) ** n, 0.0)
    return poly + bump


def test_terms_module_matches_formulas_and_cpp_table():
    np.testing.assert_allclose(T.terms_force(TERMS, X), term_reference(X), rtol=1e-12, atol=1e-9)
    d = add_terms(_core.Damper.linear(0.0), TERMS)
    f, st = forces(d)
    np.testing.assert_allclose(f, term_reference(X), rtol=1e-12, atol=1e-9)
    # the bump stop resists extension beyond +x_free and compression beyond -x_free
    assert T.term_force(TERMS[1], 0.07) > 0 > T.term_force(TERMS[1], -0.07)
    assert T.term_force(TERMS[1], 0.05) == 0
    # every C++ kind has a Python mirror with the same parameter count, and vice versa
    assert set(_core.TERM_KINDS) == set(T.KINDS)
    for k, (n, _) in _core.TERM_KINDS.items():
        assert n == len(T.KINDS[k].params)


def test_hybrid_equals_terms_plus_mlp():
    m = random_model(["velocity", "acceleration", "voltage"], seed=7, terms=TERMS)
    f, st = forces(damper_from_model(m))
    mlp = numpy_forward(m, np.stack([V, A, U], axis=1))
    np.testing.assert_allclose(f, mlp + term_reference(X), rtol=1e-12, atol=1e-8)


@pytest.mark.parametrize("kind, params, code", [
    ("gas_spring", [1.0], "unknown kind"), ("bump_stop", [0.1, 1.0], "DN_E_SIZE"),
    ("bump_stop", [-0.1, 1.0, 1.0], "DN_E_PARAM"), ("position_poly", [0, 0, np.nan, 0], "NONFINITE"),
])
def test_bad_terms_are_refused(kind, params, code):
    with pytest.raises(ValueError, match=code):
        _core.Damper.linear(1.0).add_term(kind, np.array(params, dtype=float))
    with pytest.raises(ValueError):
        T.validate({"kind": kind, "params": params})
