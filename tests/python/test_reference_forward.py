"""dampnet.reference, the one numpy MLP forward, against torch and the C++ kernel, and its users.

Tolerance: 1e-12 of the model's output range (2 / |out_gain|) for float64 against float64
(measured worst over 40 random models: 3e-15 of the range; the kernel sums in another order).
"""

from __future__ import annotations

import numpy as np
import pytest

from dampnet import _core
from dampnet.diagnosis.context import model_force
from dampnet.latency.python_bench import numpy_forward
from dampnet.model import MlpModel
from dampnet.reference import forward_of, mlp_forward
from dampnet.sim.quarter_car.reference_loop import NeuralLoopDamper
from dampnet.training import torch_forward

TOL = 1e-12  # of the output range
FEATS = ["velocity", "acceleration", "displacement", "voltage", "temperature", "velocity_lag",
         "friction_state", "current"]


def random_model(seed: int) -> MlpModel:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 9))
    h1 = int(rng.integers(1, 20))
    two = bool(rng.integers(0, 2))
    h2 = int(rng.integers(1, 12))
    lo = rng.uniform(-10, 0, n)
    hi = lo + rng.uniform(0.1, 20, n)
    return MlpModel(w1=rng.normal(size=(h1, n)), b1=rng.normal(size=h1),
                    w2=rng.normal(size=(h2, h1)) if two else None, b2=rng.normal(size=h2) if two else None,
                    w_out=rng.normal(size=h2 if two else h1), b_out=float(rng.normal()),
                    in_offset=lo, in_gain=2 / (hi - lo), out_offset=float(rng.uniform(-3000, 0)),
                    out_gain=float(rng.uniform(1e-4, 1e-2)), sat_lo=lo, sat_hi=hi, features=FEATS[:n],
                    units=["-"] * n, activation=["tanh", "sigmoid"][seed % 2],
                    feature_params={p: 0.01 for p in _core.FEATURE_PARAM_NAMES})


def hostile_rows(model: MlpModel, seed: int, n: int = 200) -> np.ndarray:
    """Inputs within, beyond and far beyond the range, and NaN / +Inf / -Inf in every position."""
    rng = np.random.default_rng(seed + 1000)
    lo, hi = model.sat_lo, model.sat_hi
    span = hi - lo
    X = lo + span * rng.uniform(-0.5, 1.5, (n, model.n_inputs))
    X[::7] *= 1e6
    for i, bad in enumerate((np.nan, np.inf, -np.inf)):
        X[i::11, rng.integers(0, model.n_inputs)] = bad
    X[-1] = np.nan
    X[-2] = np.inf
    return X


def kernel(model: MlpModel, X: np.ndarray) -> np.ndarray:
    y, status, _ = model.core().predict(np.ascontiguousarray(X))
    assert np.all(status >= 0)  # warnings only (saturated, non-finite input)
    return y


@pytest.mark.parametrize("seed", range(12))
def test_reference_matches_torch_and_the_kernel_on_hostile_inputs(seed):
    model = random_model(seed)
    X = hostile_rows(model, seed)
    got = mlp_forward(model, X)
    scale = 2.0 / abs(model.out_gain)
    assert got.shape == (len(X),) and np.all(np.isfinite(got))
    np.testing.assert_allclose(got, kernel(model, X), rtol=0, atol=TOL * scale)
    np.testing.assert_allclose(got, torch_forward(model, X), rtol=0, atol=TOL * scale)


def test_nan_is_the_centre_of_the_range_and_inf_the_limit():
    model = random_model(3)
    mid = 0.5 * (model.sat_lo + model.sat_hi)
    f = forward_of(model)
    assert f(np.full(model.n_inputs, np.nan)) == f(mid)
    assert f(np.full(model.n_inputs, np.inf)) == f(model.sat_hi)
    assert f(np.full(model.n_inputs, -np.inf)) == f(model.sat_lo)
    with pytest.raises(ValueError, match=f"expected {model.n_inputs} inputs"):
        f(np.zeros(model.n_inputs + 1))


@pytest.mark.parametrize("seed", [0, 5])
def test_the_users_of_the_numpy_forward_agree_with_the_kernel_on_nan_rows(seed):
    """The diagnosis, the Python reference loop and the latency benchmark's numpy candidate."""
    model = random_model(seed)
    X = hostile_rows(model, seed, n=40)
    want = kernel(model, X)
    atol = TOL * 2.0 / abs(model.out_gain)
    np.testing.assert_allclose(model_force(model, X, None), want, rtol=0, atol=atol)
    np.testing.assert_allclose(NeuralLoopDamper(model).forward(X), want, rtol=0, atol=atol)
    bench = numpy_forward(model)
    np.testing.assert_allclose([bench(x) for x in X], want, rtol=0, atol=atol)
