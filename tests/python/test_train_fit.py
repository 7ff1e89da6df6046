"""fit(): split, rest points, scaling and limits, reproducibility, early stopping,
provenance; torch_forward against an independent numpy forward; feature_matrix."""

import json

import numpy as np
import pytest
import torch

from dampnet.model import MlpModel
from dampnet.reference import mlp_forward
from dampnet.data import DataError, DynoTest
from dampnet.features import feature_matrix
from dampnet.training import fit, nrmse, torch_forward
from dampnet.training.synthetic import damper_force, synthetic_dyno

FEATS = ["velocity", "acceleration", "voltage"]


@pytest.fixture(scope="module")
def small():
    X, y = synthetic_dyno(n_tests=60, samples_per_test=40, noise=0.01, seed=1)
    model, info = fit(X, y, features=FEATS, hidden=(8,), max_epochs=60, seed=3)
    return X, y, model, info


def test_fit_learns_the_synthetic_damper(small):
    X, y, model, info = small
    assert info.epochs > 0 and info.stop_reason
    # 1 % noise: test error close to the noise floor, far below a constant fit (~0.2).
    assert info.metrics["test"] < 0.03
    assert nrmse(torch_forward(model, X[info.test_idx]), y[info.test_idx]) == pytest.approx(
        info.metrics["test"], rel=1e-12)
    assert info.history[-1]["train"] < info.history[0]["train"]


def test_split_is_disjoint_and_70_15_15(small):
    X, _, _, info = small
    idx = np.concatenate([info.train_idx, info.val_idx, info.test_idx])
    assert sorted(idx.tolist()) == list(range(len(X)))
    assert (info.n_train, info.n_val, info.n_test) == (1680, 360, 360)


def test_scaling_and_saturation_cover_the_training_range(small):
    X, y, model, info = small
    np.testing.assert_array_equal(model.sat_lo, X.min(axis=0))  # 0 lies inside: rest points add nothing
    np.testing.assert_array_equal(model.sat_hi, X.max(axis=0))
    scaled = (X - model.in_offset) * model.in_gain - 1
    np.testing.assert_allclose(scaled.min(axis=0)[:2], -1, atol=1e-15)
    np.testing.assert_allclose(scaled.max(axis=0)[:2], 1, atol=1e-15)
    assert model.out_offset == pytest.approx(y.min())
    assert model.out_gain == pytest.approx(2 / (y.max() - y.min()))
    assert model.features == FEATS and model.units == ["m/s", "m/s^2", "V"]


def test_provenance_in_meta_round_trips_through_json(small, tmp_path):
    _, _, model, info = small
    for key in ("algorithm", "settings", "training_time_s", "torch_version", "seed", "metrics"):
        assert key in model.meta
    assert model.meta["torch_version"] == torch.__version__
    assert model.meta["settings"]["mu_dec"] == 0.1
    back = MlpModel.load(model.save(tmp_path / "model.json"))
    assert back.meta == json.loads(json.dumps(model.meta))
    json.dumps(info.to_dict())


def test_same_seed_gives_identical_weights_and_another_seed_does_not():
    X, y = synthetic_dyno(n_tests=20, samples_per_test=30, seed=2)
    kw = dict(features=FEATS, hidden=(5,), max_epochs=15)
    a, _ = fit(X, y, seed=7, **kw)
    b, _ = fit(X, y, seed=7, **kw)
    c, _ = fit(X, y, seed=8, **kw)
    np.testing.assert_array_equal(a.w1, b.w1)
    np.testing.assert_array_equal(a.w_out, b.w_out)
    assert a.b_out == b.b_out
    assert not np.array_equal(a.w1, c.w1)


def test_rest_points_are_at_rest_at_measured_voltages():
    X, y = synthetic_dyno(n_tests=60, samples_per_test=20, seed=3)
    def grab(rec):  # stop after one epoch: only the data set-up matters here
        return True

    _, info = fit(X, y, features=FEATS, hidden=(3,), max_epochs=5, progress=grab)
    assert info.stop_reason == "stopped by caller" and info.epochs == 1
    assert info.n_rest_points == int(np.ceil(0.01 * info.n_train))
    from dampnet.training.rest_points import rest_points
    Z = rest_points(X, FEATS, 0.01, np.random.default_rng(0))
    assert np.all(Z[:, :2] == 0)  # velocity and acceleration at rest
    assert set(Z[:, 2]) <= set(X[:, 2])  # voltage copied from measured samples
    # Voltage alone has no at-rest value: no rest points.
    assert len(rest_points(X[:, 2:], ["voltage"], 0.01, np.random.default_rng(0))) == 0
    _, off = fit(X, y, features=FEATS, hidden=(3,), max_epochs=1, rest_target="none")
    assert off.n_rest_points == 0


def test_the_rest_force_is_estimated_through_friction_and_asymmetric_valves():
    """Analytic damper: gas force -273 N, a 40 N friction step at v = 0 (tanh over 2 mm/s),
    rebound slope 4000 N s/m, compression 1500 N s/m, 2 N noise: the estimate is the gas force
    within 3 N, the friction step within 8 N (its tanh reads
    as a smaller step)."""
    from dampnet.training.rest_points import rest_force

    rng = np.random.default_rng(0)
    v = rng.uniform(-1.0, 1.0, 20_000) * rng.uniform(0, 1, 20_000)   # dense near 0, as sine tests are
    F = -273.0 + 40.0 * np.tanh(v / 0.002) + np.where(v > 0, 4000.0, 1500.0) * v + rng.normal(0, 2.0, v.size)
    X = np.column_stack([v, np.zeros_like(v), np.full_like(v, 2.0)])
    r = rest_force(X, F, FEATS)
    assert r.source == "estimated" and r.rows > 1000
    assert abs(r.force_N + 273.0) < 3.0 and abs(r.friction_N - 40.0) < 8.0, r
    # one common slope (no sign split) would be biased by about (4000 - 1500) / 2 * E|v| (~30 N)
    near = np.abs(v) <= 0.05
    b0 = np.linalg.lstsq(np.column_stack([np.ones(near.sum()), v[near], np.sign(v[near])]), F[near], rcond=None)[0][0]
    assert abs(b0 + 273.0) > 10.0
    # a gas spring (the force at rest follows the displacement) and low-speed damping that grows
    # with the voltage: each rest row's target follows its own displacement, not the voltage
    x = rng.uniform(-0.02, 0.02, v.size)
    u = rng.choice([0.0, 2.5, 5.0], v.size)
    F2 = -273.0 + 4000.0 * x + 40.0 * np.tanh(v / 0.002) + (1500.0 + 800.0 * u) * v + rng.normal(0, 2.0, v.size)
    feats4 = FEATS + ["displacement"]
    X4 = np.column_stack([v, np.zeros_like(v), u, x])
    Z = X4[:50].copy()
    Z[:, :2] = 0.0
    r4 = rest_force(X4, F2, feats4, Z)
    assert np.max(np.abs(r4.targets(Z) - (-273.0 + 4000.0 * Z[:, 3]))) < 3.0
    assert abs(r4.force_N - np.mean(-273.0 + 4000.0 * Z[:, 3])) < 2.0
    # no velocity input, or too few rows on one side: the thesis's 0 N, said
    assert rest_force(X[:, 1:], F, FEATS[1:]).force_N == 0.0
    one_side = rest_force(np.abs(X), F, FEATS)
    assert one_side.force_N == 0.0 and "fewer than 20" in one_side.source


def test_rest_points_hold_the_damper_s_own_force_at_rest_when_asked():
    # A target 300 N higher everywhere: rest_target="estimated" (the default) asks for about 300 N at
    # rest; "zero" (the thesis's 0 N) still records the estimate and trains as the thesis did.
    X, y = synthetic_dyno(n_tests=60, samples_per_test=30, noise=0.0, seed=4)
    y = y + 300.0
    rest = np.array([[0.0, 0.0, v] for v in np.unique(X[:, 2])])
    kw = dict(features=FEATS, hidden=(8,), max_epochs=40, seed=1, rest_fraction=0.2)
    model, _ = fit(X, y, rest_target="estimated", **kw)
    meta = model.meta["rest_force"]
    assert meta["source"] == "estimated" and abs(meta["force_N"] - 300.0) < 15.0, meta
    assert meta["target"] == "estimated" and meta["target_N"] == pytest.approx(meta["force_N"], abs=1e-3)
    assert np.abs(torch_forward(model, rest) - 300.0).mean() < 30.0
    zero, _ = fit(X, y, rest_target="zero", **kw)
    zm = zero.meta["rest_force"]
    assert zm["target"] == "zero" and zm["target_N"] == 0.0 and zm["force_N"] == meta["force_N"]
    assert np.abs(torch_forward(zero, rest) - 300.0).mean() > 2 * np.abs(torch_forward(model, rest) - 300.0).mean()
    off, _ = fit(X, y, features=FEATS, hidden=(8,), max_epochs=1, seed=1, rest_target="none")
    assert off.meta["rest_force"]["source"] == "no rest points"
    with pytest.raises(ValueError, match=r"rest_target \(--rest-target, .*\): expected one of estimated, "
                                         r"zero, none, got 'gas'"):
        fit(X, y, features=FEATS, hidden=(3,), max_epochs=1, rest_target="gas")


def test_validation_early_stopping_returns_the_best_epoch():
    # Few, noisy samples and a big net: validation error must turn up.
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(80, 3))
    y = damper_force(X[:, 0], 10 * X[:, 1], 2 + X[:, 2]) + 300 * rng.standard_normal(80)
    model, info = fit(X, y, features=FEATS, hidden=(30,), max_epochs=500, seed=0)
    assert "max_fail" in info.stop_reason
    assert info.epochs == info.best_epoch + 6
    vals = [h["val"] for h in info.history]
    assert vals[info.best_epoch] == min(vals)
    # The returned weights are the best-validation ones, not the last.
    va = info.val_idx
    best_val_mse_scaled = vals[info.best_epoch]
    err = (torch_forward(model, X[va]) - y[va]) * model.out_gain
    assert np.mean(err ** 2) == pytest.approx(best_val_mse_scaled, rel=1e-9)


@pytest.mark.parametrize("algorithm", ["br", "scg", "adam"])
def test_every_algorithm_trains_through_fit(algorithm):
    X, y = synthetic_dyno(n_tests=40, samples_per_test=25, seed=5)
    model, info = fit(X, y, features=FEATS, hidden=(5,), algorithm=algorithm, max_epochs=40)
    assert model.meta["algorithm"] == algorithm and info.epochs > 0
    assert info.history[-1]["train"] < info.history[0]["train"]
    if algorithm == "br":
        assert 0 < info.stats["gamma"] <= 5 * 3 + 5 + 5 + 1
        assert model.meta["max_fail"] is None


def test_fit_rejects_bad_input():
    X, y = synthetic_dyno(n_tests=4, samples_per_test=10)
    with pytest.raises(ValueError, match="columns"):
        fit(X, y, features=["velocity"])
    with pytest.raises(ValueError, match="finite"):
        fit(np.where(X == X[0, 0], np.nan, X), y, features=FEATS)
    with pytest.raises(ValueError, match="algorithm"):
        fit(X, y, features=FEATS, algorithm="sgd")
    with pytest.raises(KeyError, match="unknown feature"):
        fit(X, y, features=["velocity", "acceleration", "bogus"])


@pytest.mark.parametrize("activation,hidden", [("tanh", (4,)), ("sigmoid", (4, 3))])
def test_torch_forward_matches_numpy_reference_with_clamping(activation, hidden):
    rng = np.random.default_rng(0)
    h1 = hidden[0]
    m = MlpModel(w1=rng.normal(size=(h1, 3)), b1=rng.normal(size=h1),
                 w2=rng.normal(size=(hidden[1], h1)) if len(hidden) > 1 else None,
                 b2=rng.normal(size=hidden[1]) if len(hidden) > 1 else None,
                 w_out=rng.normal(size=hidden[-1]), b_out=0.3, in_offset=[-1.0, -20.0, 0.0],
                 in_gain=[1.0, 0.05, 0.4], out_offset=-500.0, out_gain=1 / 800, sat_lo=[-1.0, -20.0, 0.0],
                 sat_hi=[1.0, 20.0, 5.0], features=FEATS, units=["m/s", "m/s^2", "V"],
                 activation=activation)
    X = rng.uniform(-2, 2, size=(50, 3)) * [1, 20, 5]
    X[0] = [np.nan, np.inf, -np.inf]
    got = torch_forward(m, X)
    np.testing.assert_allclose(got, mlp_forward(m, X), rtol=1e-13, atol=1e-10)
    # Clamping: a far-out input gives the same force as the limit itself.
    assert torch_forward(m, [[9.0, 0.0, 1.0]])[0] == torch_forward(m, [[1.0, 0.0, 1.0]])[0]
    assert np.all(np.isfinite(got))


def test_torch_forward_refuses_models_with_physics_terms(small):
    _, _, model, _ = small
    m = MlpModel.from_dict({**model.to_dict(), "terms": [{"kind": "gas", "params": [100.0]}]})
    with pytest.raises(ValueError, match="physics terms"):
        torch_forward(m, np.zeros((1, 3)))


def test_feature_matrix_stacks_named_channels_and_names_what_is_missing():
    t = np.arange(3.0) * 0.01
    t1 = DynoTest("a", t, {"velocity": np.arange(3.0), "voltage": np.full(3, 2.0)})
    t2 = DynoTest("b", t[:2], {"velocity": np.arange(2.0)})
    X = feature_matrix([t1], ["voltage", "velocity"])
    np.testing.assert_array_equal(X, [[2, 0], [2, 1], [2, 2]])
    with pytest.raises(DataError, match=r"test b: feature 'voltage' needs channel 'voltage'.*velocity"):
        feature_matrix([t1, t2], ["velocity", "voltage"])
    with pytest.raises(DataError, match="unknown feature"):
        feature_matrix([t1], ["speed"])
