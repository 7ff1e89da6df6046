"""The linearised acceleration scheme's guard (DN_ACCEL_LINEAR, issue 14 item 1).

Its Newton step changes the force by -dF/da g / g' with g' = 1 + k dF/da; where the
damper's negative apparent mass nearly cancels the reduced mass (g' -> 0) that change
is unbounded. Below g' = DN_ACCEL_LINEAR_MIN_SLOPE the loop keeps the explicit value
and reports DN_W_ACCEL_FALLBACK; above it, nothing changes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dampnet import _core
from dampnet.sim.quarter_car.loop import S, QuarterCar, damper_from_model
from dampnet.model import MlpModel
from test_loop_control import MS, MUS, added_mass_run, linear_mlp
from test_loop_quarter_car import random_road

ROOT = Path(__file__).resolve().parents[2]
K_REL = 1 / MS + 1 / MUS  # da/dF of the relative acceleration [1/kg]
FALLBACK = _core.DN_W_ACCEL_FALLBACK
MIN_SLOPE = 0.5  # DN_ACCEL_LINEAR_MIN_SLOPE (dampnet.h)


def hil_road(dt=1e-3, t_end=3.0):
    """Issue 14's plain road: z_r = 0.015 sin(2 pi 1.3 t) + 0.005 sin(2 pi 11 t) [m], exact rate."""
    t = np.arange(0.0, t_end, dt)
    w1, w2 = 2 * np.pi * 1.3, 2 * np.pi * 11.0
    return (0.015 * np.sin(w1 * t) + 0.005 * np.sin(w2 * t),
            0.015 * w1 * np.cos(w1 * t) + 0.005 * w2 * np.cos(w2 * t))


@pytest.fixture(scope="module")
def default_model():
    return MlpModel.load(ROOT / "export" / "dn_model_default.json")


def force_range(model):
    """[min, max] of the model's training forces [N] (mapminmax of the output)."""
    return model.out_offset, model.out_offset + (1.0 - model.out_ymin) / model.out_gain


def dfda(model, x):
    """dF/da [kg] of the double kernel at samples x by central differences (clamped at the
    saturation limits, where the kernel's slope is 0 outside)."""
    ia = model.features.index("acceleration")
    h = 1e-5 * (model.sat_hi[ia] - model.sat_lo[ia])
    xp, xm = x.copy(), x.copy()
    xp[:, ia] = np.minimum(x[:, ia] + h, model.sat_hi[ia])
    xm[:, ia] = np.maximum(x[:, ia] - h, model.sat_lo[ia])
    with np.errstate(invalid="ignore", divide="ignore"):
        d = (model.predict(xp) - model.predict(xm)) / (xp[:, ia] - xm[:, ia])
    return np.where(xp[:, ia] > xm[:, ia], d, 0.0)


@pytest.mark.parametrize("damper_eval", ["per_step", "per_stage"])
@pytest.mark.parametrize("single", [True, False], ids=["float", "double"])
def test_hil_configuration_has_no_force_spikes(default_model, damper_eval, single):
    """The HIL configuration (default model, linear acceleration, on-off skyhook) on issue
    14's road: before the guard 30-385 kN spikes (range -1.6..2.6 kN); now every force stays
    within the model's force range plus 10 % of its width, and the fallback is reported."""
    z, zd = hil_road()
    car = QuarterCar(damper_from_model(default_model, single=single),
                     {"damper_eval": damper_eval, "accel_feature": "linear"},
                     {"kind": "skyhook_onoff"})
    out = car.simulate(z, zd)
    lo, hi = force_range(default_model)
    margin = 0.1 * (hi - lo)
    print(f"max |F| {np.abs(out['force']).max():.0f} N, fallback in "
          f"{np.count_nonzero(out['status'] & FALLBACK)} of {z.size} steps")
    assert np.all(out["status"] >= 0)
    assert np.all((out["force"] >= lo - margin) & (out["force"] <= hi + margin))
    assert np.count_nonzero(out["status"] & FALLBACK) > 0


def test_fallback_is_reported_exactly_where_the_step_is_ill_conditioned(default_model):
    """Per step (one evaluation per step, at the explicit acceleration a0 = a_rel(F) +
    k (F - f_last)): the bit is set exactly in the steps where g'(a0) = 1 + k dF/da(a0) <
    1/2 (dF/da by finite differences of the kernel, independent of the loop's slope); in
    those steps the force is the model's own value at a0 (no extrapolation)."""
    z, zd = hil_road()
    car = QuarterCar(damper_from_model(default_model), {"damper_eval": "per_step",
                                                        "accel_feature": "linear"},
                     {"kind": "skyhook_onoff"})
    out = car.simulate(z, zd)
    n = z.size - 1  # the last row reports without a following step
    force, f_last = out["force"][:n], out["state"][:n, S["f_last"]]
    a0 = (out["acc_s"] - out["acc_us"])[:n] + K_REL * (force - f_last)
    x = np.column_stack([out["v"][:n], a0, out["control"][:n]])
    gp = 1.0 + K_REL * dfda(default_model, x)
    flagged = (out["status"][:n] & FALLBACK) != 0
    clear = np.abs(gp - MIN_SLOPE) > 1e-3  # finite-difference tolerance
    print(f"g'(a0) min {gp.min():.3f}; flagged {flagged.sum()} steps")
    assert flagged.sum() > 0
    np.testing.assert_array_equal(flagged[clear], (gp < MIN_SLOPE)[clear])
    np.testing.assert_allclose(force[flagged], default_model.predict(x[flagged]), rtol=1e-9,
                               atol=1e-9)


def test_negative_added_mass_inside_the_region_still_follows_the_exact_solution():
    """F = c v + m_a a with m_a = -15 kg (g' = 0.60 >= 1/2): the linearised step is taken
    (no fallback) and, exact for a force linear in a, matches the exact implicit system
    (scipy on its mass matrix) to < 1e-6 relative RMS."""
    (err, evals, status), = added_mass_run(-15.0, "linear", dts=(1e-3,))
    assert err < 1e-6
    assert evals == 4.0
    assert not np.any(status & FALLBACK)


def test_negative_added_mass_outside_the_region_is_the_explicit_scheme():
    """m_a = -30 kg (g' = 0.21 < 1/2): every evaluation falls back to the explicit value,
    so the run is the explicit scheme's, bit for bit, and every step reports the fallback."""
    z, zd = random_road(seed=8)
    t = np.arange(3001) * 1e-3
    runs = {}
    for mode in ("linear", "explicit"):
        car = QuarterCar(damper_from_model(linear_mlp(1500.0, -30.0, eps=1e-9)),
                         {"dt": 1e-3, "accel_feature": mode})
        runs[mode] = car.simulate(z(t), zd(t))
    assert np.all(runs["linear"]["status"][:-1] & FALLBACK)
    assert not np.any(runs["explicit"]["status"] & FALLBACK)
    np.testing.assert_array_equal(runs["linear"]["state"], runs["explicit"]["state"])
    np.testing.assert_array_equal(runs["linear"]["force"], runs["explicit"]["force"])
    assert np.all(np.isfinite(runs["linear"]["state"]))


def test_status_str_explains_the_fallback_and_its_combinations():
    text = _core.status_str(FALLBACK)
    assert "DN_W_ACCEL_FALLBACK" in text and "explicit" in text
    both = _core.status_str(FALLBACK | _core.DN_W_SATURATED)
    assert "DN_W_SATURATED|DN_W_ACCEL_FALLBACK" in both and "clamped" in both
    assert "unknown" in _core.status_str(1 << 20)
