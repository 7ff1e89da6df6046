"""Each named effect changes the force the way its physics says (sign, scaling, temperature, steps)."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.rig import EFFECTS, Effect, TruthParams, generate, truth_force
from dampnet.rig.effects import register

P = TruthParams()
FS = 5000.0
DT = 1 / FS


def _sine(f=1.0, amp=0.0254, seconds=2.0):
    t = np.arange(int(seconds * FS) + 1) * DT
    w = 2 * np.pi * f
    return t, amp * np.sin(w * t), amp * w * np.cos(w * t)


def _effect_part(effect, x, v, u=2.25, temp=None):
    base = truth_force(x, v, np.full(x.shape, u), temp, dt=DT)
    return truth_force(x, v, np.full(x.shape, u), temp, dt=DT, effects=[effect]) - base


def test_gas_spring_is_a_stiffening_polytropic_spring():
    x = np.linspace(-0.0254, 0.0254, 201)
    v = np.zeros_like(x)
    f = _effect_part("gas_spring", x, v)
    assert np.all(np.sign(f[x != 0]) == np.sign(x[x != 0]))          # resists displacement from mid-stroke
    g = EFFECTS["gas_spring"]
    k_small = g.polytropic_n * P.gas_pressure_pa * P.rod_area_m2 ** 2 / g.gas_volume_m3
    slope = (f[101] - f[99]) / (x[101] - x[99])
    assert slope == pytest.approx(k_small, rel=1e-3)                   # n p0 A^2 / V0 at mid-stroke
    assert -f[0] > f[-1]                                                # stiffer in compression
    # independent: isentropic pressure at full compression
    v_gas = g.gas_volume_m3 - P.rod_area_m2 * 0.0254
    p_full = P.gas_pressure_pa * (g.gas_volume_m3 / v_gas) ** g.polytropic_n
    assert f[0] == pytest.approx(-(p_full - P.gas_pressure_pa) * P.rod_area_m2, rel=1e-12)


def test_hot_oil_damps_less_by_the_viscosity_ratio():
    t, x, v = _sine(3.0)
    u = np.full(t.size, 0.0)
    cold = truth_force(x, v, u, np.full(t.size, 25.0), dt=DT)
    hot = truth_force(x, v, u, np.full(t.size, 65.0), dt=DT)
    reb = v > 0.1
    assert np.all(hot[reb] < cold[reb]) and np.all(hot[v < -0.1] > cold[v < -0.1])
    # only the laminar loss depends on temperature: dF = R_lam (mu(25)/mu_ref - mu(65)/mu_ref) A^2 v_h
    mu = lambda tc: np.exp(P.viscosity_b_k * (1 / (tc + 273.15) - 1 / (P.temperature_ref_c + 273.15)))
    a = P.annulus_area_m2
    from dampnet.features import first_order_lag
    expect = P.laminar_resistance_pa_s_m3 * (mu(25.0) - mu(65.0)) * a * a * first_order_lag(v, DT, P.compressibility_tau_s)
    np.testing.assert_allclose(cold - hot, expect, rtol=1e-9, atol=1e-9)


def test_thermal_rig_records_temperature_varying_between_and_within_tests():
    ds = generate("quick", effects=["thermal"], seed=3)
    starts = [t.channels["temperature"][0] for t in ds.tests]
    assert all(25 <= s <= 65.5 for s in starts) and np.ptp(starts) > 10
    hard = [t for t in ds.tests if t.frequency_hz == 3.0 and t.control_nominal == 0.0][0]
    rise = hard.channels["temperature"][-200:].mean() - hard.channels["temperature"][:200].mean()
    energy = np.sum(np.clip(hard.channels["force"] * hard.channels["velocity"], 0, None)) * hard.dt
    assert 0.2 < rise < 1.2 * energy / EFFECTS["thermal"].heat_capacity_j_k    # heats, at most E/C
    assert "temperature" not in generate("quick", seed=3).tests[0].channels


def test_valve_lag_slows_the_force_response_to_a_voltage_step():
    n = 3000
    t = np.arange(n) * DT
    v = np.full(n, 0.3)
    x = -0.02 + v * t
    u = np.where(t < 0.2, 0.0, 5.0)
    k = int(0.2 * FS)
    fast = truth_force(x, v, u, dt=DT)
    slow = truth_force(x, v, u, dt=DT, effects=["valve_lag"])
    jump = fast[k - 1] - fast[-1]
    assert jump > 500
    k15, k120 = k + int(0.015 * FS), k + int(0.120 * FS)
    assert abs(fast[k15] - fast[-1]) < 0.01 * jump                      # no lag: settled in 15 ms
    assert (slow[k15] - slow[-1]) > 0.10 * jump                          # 40 ms valve: still far off
    assert abs(slow[k120] - slow[-1]) < 0.01 * jump                      # settled after 9 tau
    np.testing.assert_allclose(slow[:k], fast[:k], rtol=1e-12)


def test_valve_lag_rig_steps_the_voltage_within_tests():
    ds = generate("quick", effects=["valve_lag"], seed=0)
    period = EFFECTS["valve_lag"].step_period_s
    for t in ds.tests:
        u = np.round(t.channels["voltage"] * 4) / 4          # noise is mV; levels are 0.25 V apart or more
        levels = np.unique(u)
        assert len(levels) == 2 and np.ptp(levels) >= 2.0 - 1e-9
        assert abs(u[0] - t.control_nominal) < 0.05
        switches = np.flatnonzero(np.diff(u) != 0)
        assert len(switches) >= 1
        np.testing.assert_allclose(np.diff(switches) / FS, period, atol=2 / FS)


def test_stick_slip_friction_breaks_away_at_reversals():
    t, x, v = _sine(0.5)
    f = _effect_part("friction", x, v)
    fr = EFFECTS["friction"]
    fast = np.abs(v) > 0.05
    assert np.max(np.abs(f[fast])) < 1.0                                  # sliding: same as Coulomb
    rev = np.flatnonzero(np.diff(np.sign(v)) != 0)[0]          # extension -> compression
    new = np.sign(v[rev + 5])
    lugre = f + P.seal_friction_n * np.tanh(v / P.seal_friction_v_eps_m_s)   # the seal force itself
    after = lugre[rev + 1: rev + int(0.2 * FS)]
    # stick: the bristles are still deflected the old way just after the reversal
    assert np.sign(after[0]) == -new
    # breakaway: the force then exceeds the sliding level in the new direction, up to the static level
    peak = np.max(new * after)
    assert fr.coulomb_n + 0.5 * (fr.static_n - fr.coulomb_n) < peak <= fr.static_n * 1.05
    # the smooth Coulomb model has neither: it flips at once and never exceeds F_c
    smooth = P.seal_friction_n * np.tanh(v[rev + 1: rev + int(0.2 * FS)] / P.seal_friction_v_eps_m_s)
    assert np.max(new * smooth) <= P.seal_friction_n


def test_bump_stop_acts_only_near_full_compression_and_grows_with_penetration_squared():
    x = np.linspace(-0.0254, 0.0254, 509)
    f = _effect_part("bump_stop", x, np.zeros_like(x))
    b = EFFECTS["bump_stop"]
    engage = -(P.stroke_m / 2 - b.travel_m)
    assert np.all(f[x > engage] == 0) and np.all(f[x < engage] < 0)
    d = engage - x[x < engage]
    np.testing.assert_allclose(f[x < engage], -b.stiffness_n_m2 * d * d, rtol=1e-12)
    comp = _effect_part("bump_stop", x, np.full_like(x, -0.2))
    rel = _effect_part("bump_stop", x, np.full_like(x, 0.2))
    inside = x < engage
    assert np.all(comp[inside] < f[inside]) and np.all(rel[inside] > f[inside])   # hysteresis


def test_effects_registry_accepts_a_user_effect():
    from dampnet.effects import CATALOGUE, EffectInfo, register_effect

    class Offset(Effect):
        name = "test_offset"

        def force(self, ctx):
            return np.full(ctx.v.shape, 12.5)

    # the rig's physics is keyed by the effect catalogue: an id it does not know is refused
    with pytest.raises(ValueError, match="register it in the effect catalogue first"):
        register(Offset)
    register_effect(EffectInfo(id="test_offset", title="a constant force", physics="12.5 N, always",
                               rig="switchable", diagnosed_by=None, adds=None))
    try:
        register(Offset)
        t, x, v = _sine(1.0, seconds=0.5)
        d = truth_force(x, v, np.zeros_like(x), dt=DT, effects=["test_offset"]) - truth_force(x, v, np.zeros_like(x), dt=DT)
        np.testing.assert_allclose(d, 12.5)
        ds = generate("quick", effects=["test_offset"], seed=0)
        assert "test_offset" in ds.meta["effects"]
    finally:
        EFFECTS.pop("test_offset", None)
        CATALOGUE.pop("test_offset")
    with pytest.raises(ValueError, match="unknown effect 'test_offset'"):
        truth_force(x, v, np.zeros_like(x), dt=DT, effects=["test_offset"])
