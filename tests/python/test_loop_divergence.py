"""Issue 14 item 9 (C++ side): what a step reports when finite inputs make the
computation overflow (DN_E_DIVERGED, not the caller's DN_E_NONFINITE_INPUT), an absurd
dt refused at creation, and an MLP whose folded scaling overflows float refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dampnet import _core
from dampnet.sim.quarter_car.loop import QuarterCar, damper_from_model
from dampnet.model import MlpModel

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def default_model():
    return MlpModel.load(ROOT / "export" / "dn_model_default.json")


def dampers(model):
    return {"linear": _core.Damper.linear(1500.0),
            "neural_float": damper_from_model(model, single=True),
            "neural_double": damper_from_model(model)}


@pytest.mark.parametrize("kind", ["linear", "neural_float", "neural_double"])
@pytest.mark.parametrize("eval_mode", ["per_stage", "per_step"])
def test_finite_overflowing_road_is_divergence_and_state_kept(default_model, kind, eval_mode):
    """A road of 1e308 m is finite (not the caller's NaN/Inf) but k_t (z_us - z_r)
    overflows: DN_E_DIVERGED, the state not advanced."""
    car = QuarterCar(dampers(default_model)[kind], {"damper_eval": eval_mode})
    for _ in range(3):
        car.step(0.01, 0.0)
    before = car.state.copy()
    with pytest.raises(ValueError, match="DN_E_DIVERGED"):
        car.step(1e308, 0.0)
    np.testing.assert_array_equal(car.state, before)
    with pytest.raises(ValueError, match="DN_E_DIVERGED"):
        car.step(0.0, 1e308)
    np.testing.assert_array_equal(car.state, before)
    with pytest.raises(ValueError, match="DN_E_NONFINITE_INPUT"):  # the caller's Inf stays that
        car.step(np.inf, 0.0)


@pytest.mark.parametrize("kind", ["linear", "neural_float", "neural_double"])
def test_stiff_divergence_is_refused_or_reported_as_divergence(default_model, kind):
    """dt = 0.05 s, far beyond RK4's limit for the 11 Hz wheel hop, and a stiff tyre: refused
    when the model is made (issue 29: DN_STABLE_WDT_RK4). Within the limit, a damper far
    stiffer than any car's (20 kN s/m) still makes RK4 run away: the first error is
    DN_E_DIVERGED (at the physical bounds, long before an overflow) and the state stays
    finite and within the bounds."""
    with pytest.raises(ValueError, match="vehicle 'dt' = 0.05 .*DN_E_PARAM"):
        QuarterCar(dampers(default_model)[kind], {"dt": 0.05, "k_t": 2e7, "accel_feature": "explicit"})
    car = QuarterCar(_core.Damper.linear(20000.0), {"dt": 0.02})
    road = np.full(4000, 0.05)
    with pytest.raises(ValueError, match="DN_E_DIVERGED"):
        car.simulate(road, np.zeros_like(road))
    s = car.state
    assert np.all(np.isfinite(s)) and abs(s[1] - s[3]) <= _core.PLAUSIBLE_BOUNDS["DN_PLAUSIBLE_TRAVEL_M"][0]


@pytest.mark.parametrize("dt", [1e-320, 5e-324, 1e-12, 9.9e-10])
def test_absurd_dt_is_refused_at_creation(dt):
    with pytest.raises(ValueError, match="DN_E_PARAM"):
        QuarterCar(_core.Damper.linear(1500.0), {"dt": dt})


def test_smallest_dt_runs_and_a_road_step_is_divergence_free():
    """dt = 1e-9 s is accepted; a 1 cm road step in one such step is a finite rate (1e7 m/s)."""
    car = QuarterCar(_core.Damper.linear(1500.0), {"dt": 1e-9})
    rep = car.step(0.01, 0.0)
    assert rep["status"] >= 0 and np.all(np.isfinite(car.state))


def scaled_model(model, **changes):
    """A copy of the default model with some scaling fields replaced."""
    m = MlpModel.load(ROOT / "export" / "dn_model_default.json")
    for k, v in changes.items():
        setattr(m, k, v)
    return m


@pytest.mark.parametrize("changes", [{"out_offset": 1e39}, {"out_offset": -1e39},
                                     {"out_gain": 1e-40}, {"sat_hi": np.array([1e39, 9.1, 5.0])}])
def test_mlp_whose_scaling_overflows_float_is_refused(default_model, changes):
    """Before: created, and the float forward returned +-inf with DN_E_NONFINITE_OUTPUT (its
    fallback, out_offset, was itself inf). Now refused at creation with DN_E_PARAM."""
    m = scaled_model(default_model, **changes)
    with pytest.raises(ValueError, match="DN_E_PARAM"):
        m.core()


def test_mlp_with_large_but_float_finite_scaling_is_accepted(default_model):
    m = scaled_model(default_model, out_offset=1e30)
    y, st, _ = m.core().predict(np.array([[0.1, 1.0, 2.0]]), True)
    assert np.all(np.isfinite(y)) and np.all(st >= 0)


def test_huge_finite_state_is_divergence_also_in_forward():
    """A state of 1e308 (finite, accepted by set_state) overflows the relative motion:
    neither step nor forward reports success with a non-finite value."""
    car = QuarterCar(_core.Damper.linear(1500.0))
    s = car.state.copy()
    s[1], s[3] = 1e308, -1e308  # z_s, z_us: z_s - z_us overflows
    car.state = s
    with pytest.raises(ValueError, match="DN_E_DIVERGED"):
        car.loop.forward(0.0)
    with pytest.raises(ValueError, match="DN_E_DIVERGED"):
        car.step(0.0, 0.0)
    np.testing.assert_array_equal(car.state, s)
