"""The truth damper's base physics, its stepwise form, and the rig's plans, determinism and noise."""

from __future__ import annotations

import time

import numpy as np
import pytest
from scipy.optimize import brentq

from dampnet.rig import (EFFECTS, TruthDamper, TruthParams, controller_current, generate,
                              noise_floor_nrmse, thesis_plan, truth_force)
from dampnet.rig.truth import hydraulic_force, orifice_pressure, valve_opening

P = TruthParams()
PSI = 6894.757293168          # Pa
ROD_AREA = np.pi / 4 * (0.625 * 0.0254) ** 2


def test_controller_current_is_table2():
    volts = [0, 0.5, 1, 1.25, 1.5, 1.75, 2, 2.25, 2.5, 2.75, 3, 3.5, 4, 4.5, 5]
    milliamps = [20, 50, 100, 130, 165, 195, 240, 290, 335, 410, 440, 585, 730, 890, 1180]
    np.testing.assert_allclose(controller_current(np.array(volts, float), P), np.array(milliamps) / 1e3)


def test_orifice_solution_matches_a_root_finder():
    c = P.discharge_coefficient * np.sqrt(2 / P.oil_density_kg_m3)
    for q, a0, k, pc in [(1e-5, 3.7e-6, 1.2e-11, 0.6e6), (7e-4, 3.7e-6, 1.2e-11, 0.6e6),
                         (3e-4, 6.2e-6, 6.7e-11, 0.3e6), (7e-4, 38e-6, 6.7e-11, 0.3e6)]:
        ref = brentq(lambda dp: c * (a0 + k * max(dp - pc, 0)) * np.sqrt(dp) - q, 0, 1e9, xtol=1e-6, rtol=1e-13)
        assert orifice_pressure(np.array([q]), a0, k, pc, P)[0] == pytest.approx(ref, rel=1e-9)


def test_rebound_is_stiffer_and_voltage_lowers_damping():
    v = np.array([0.05, 0.1, 0.2, 0.48])
    for volt in (0.0, 2.25, 5.0):
        u = valve_opening(controller_current(volt, P), P)
        assert np.all(hydraulic_force(v, u, 37.8, P) > -hydraulic_force(-v, u, 37.8, P))
    forces = [hydraulic_force(v, valve_opening(controller_current(x, P), P), 37.8, P)
              for x in (0, 1, 2, 3, 4, 5)]
    assert np.all(np.diff(np.array(forces), axis=0) < 0)       # more voltage, less force, every speed
    # the change with voltage is larger in rebound than in compression
    u0, u5 = (valve_opening(controller_current(x, P), P) for x in (0.0, 5.0))
    d_reb = hydraulic_force(v, u0, 37.8, P) - hydraulic_force(v, u5, 37.8, P)
    d_com = -hydraulic_force(-v, u0, 37.8, P) + hydraulic_force(-v, u5, 37.8, P)
    assert np.all(d_reb > d_com)


def test_digressive_above_blow_off():
    v = np.linspace(0.01, 0.6, 300)
    f = hydraulic_force(v, 0.0, 37.8, P)
    slope = np.gradient(f, v)
    knee = np.argmax(slope)             # shims crack: slope is highest there and falls after
    assert 0 < knee < len(v) - 10
    assert slope[-1] < 0.5 * slope[knee]


def test_gas_preload_at_rest():
    f = truth_force(np.zeros(50), np.zeros(50), np.zeros(50), dt=2e-4)
    np.testing.assert_allclose(f, -200 * PSI * ROD_AREA, rtol=1e-12)


def test_force_lags_velocity_by_the_compressibility_time():
    fs, fq = 5000.0, 3.0
    t = np.arange(int(fs)) / fs
    v = 0.0254 * 2 * np.pi * fq * np.cos(2 * np.pi * fq * t)
    _, parts = truth_force(0.0254 * np.sin(2 * np.pi * fq * t), v, np.full(t.size, 2.25), dt=1 / fs,
                           return_parts=True)
    h = parts["hydraulic"]
    # after the velocity's downward zero crossing at t = 1/(4 fq), the hydraulic force stays positive ~tau
    k0 = int(np.ceil(fs / (4 * fq)))
    k1 = k0 + int(np.argmax(h[k0:] < 0))
    lag = (k1 - k0) / fs
    assert 0.5 * P.compressibility_tau_s < lag < 2.0 * P.compressibility_tau_s


def test_stepwise_damper_reproduces_the_vectorised_form():
    rng = np.random.default_rng(0)
    n, dt = 3000, 2e-4
    t = np.arange(n) * dt
    x = 0.02 * np.sin(2 * np.pi * 2 * t) - 0.008 * (t > 0.3)
    v = np.gradient(x, dt) + rng.normal(0, 0.01, n)
    u = np.where((t // 0.1) % 2 == 0, 1.0, 4.0)
    temp = 30 + 5 * t
    effects = list(EFFECTS)
    ref = truth_force(x, v, u, temp, dt=dt, effects=effects)
    d = TruthDamper(effects=effects)
    got = np.array([d.step(dt, x[k], v[k], u[k], temp[k]) for k in range(n)])
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-6)
    d.reset()
    assert d.step(dt, x[0], v[0], u[0], temp[0]) == pytest.approx(ref[0], rel=1e-12)


def test_thesis_plan_covers_two_cycles_at_5khz_and_generates_fast():
    plan = thesis_plan()
    specs = plan.specs()
    assert len(specs) == 180 and specs[0]["test_id"] == "T001" and specs[-1]["test_id"] == "T180"
    assert sorted({s["frequency_hz"] for s in specs}) == pytest.approx([0.25 * k for k in range(1, 13)])
    assert len({s["voltage_v"] for s in specs}) == 15
    for s in specs:
        assert s["n"] >= 10000 and (s["n"] - 1) / 5000.0 * s["frequency_hz"] >= 2.0 - 1e-9
    t0 = time.perf_counter()
    ds = generate("thesis", seed=0)
    assert time.perf_counter() - t0 < 10.0
    assert [t.test_id for t in ds.tests[:15]] == [f"T{k:03d}" for k in range(1, 16)]
    assert all(t.frequency_hz == 0.25 for t in ds.tests[:15])
    assert ds.tests[7].control_nominal == 2.25


def test_rig_is_deterministic_and_records_what_it_did():
    a = generate("quick", effects=["thermal"], seed=5)
    b = generate("quick", effects=["thermal"], seed=5)
    c = generate("quick", effects=["thermal"], seed=6)
    for ta, tb, tc in zip(a.tests, b.tests, c.tests):
        for k in ta.channels:
            assert np.array_equal(ta.channels[k], tb.channels[k])
        assert not np.array_equal(ta.channels["force"], tc.channels["force"])
    m = a.meta
    assert m["seed"] == 5 and m["plan"]["name"] == "quick" and "thermal" in m["effects"]
    assert m["truth_params"]["gas_pressure_pa"] == pytest.approx(200 * PSI)
    assert m["noise"]["force_n"] > 0


def test_quick_plan_spans_frequencies_and_voltages():
    ds = generate("quick", seed=0)
    f = {t.frequency_hz for t in ds.tests}
    v = {t.control_nominal for t in ds.tests}
    assert min(f) == 0.25 and max(f) == 3.0 and min(v) == 0.0 and max(v) == 5.0 and 2.25 in v


def test_noise_floor_matches_the_measured_noise():
    ds = generate("quick", seed=2, truth_channels=True)
    floor = noise_floor_nrmse(ds)
    f = ds.concat("force")
    empirical = np.std(f - ds.concat("true_force")) / np.std(f)
    assert floor == pytest.approx(empirical, rel=0.03)
    with pytest.raises(ValueError, match="no rig noise record"):
        noise_floor_nrmse(ds.subset(ds.tests).__class__(ds.tests, "x", {}))


def test_velocity_and_displacement_noise_are_as_recorded():
    ds = generate("quick", seed=4, truth_channels=True)
    t = ds.tests[4]
    w = 2 * np.pi * t.frequency_hz
    v_true = t.amplitude_m * w * np.cos(w * t.time)
    assert np.std(t.channels["velocity"] - v_true) == pytest.approx(ds.meta["noise"]["velocity_m_s"], rel=0.05)


def test_a_plan_file_with_steps_and_random_excitation(tmp_path):
    import json

    sine = tmp_path / "steps.json"
    sine.write_text(json.dumps({"frequencies_hz": [2.0], "amplitudes_m": [0.01, 0.02], "voltages_v": [1.0, 4.0],
                                "samples": 2000, "control": {"waveform": "steps", "period_s": 0.1}}))
    ds = generate(str(sine), seed=0)
    assert ds.meta["plan"]["name"] == "steps" and len(ds.tests) == 4
    t = ds.tests[0]
    assert len(t) == 5001                                             # two cycles at 2 Hz = 1 s at 5 kHz, + 1
    assert np.ptp(t.channels["displacement"]) == pytest.approx(0.02, rel=0.01)
    u = np.round(t.channels["voltage"])
    assert set(np.unique(u)) == {1.0, 4.0} and u[0] == 1.0
    rnd = tmp_path / "road.json"
    rnd.write_text(json.dumps({"frequencies_hz": [], "amplitudes_m": [0.005], "voltages_v": [2.0],
                               "excitation": "random", "band_hz": [0.5, 8.0], "duration_s": 3.0}))
    road = generate(str(rnd), seed=1, truth_channels=True)
    r = road.tests[0]
    assert r.frequency_hz is None and len(r) == 15000
    assert np.std(r.channels["displacement"]) == pytest.approx(0.005, rel=0.02)
    # the rig's velocity is the derivative of its displacement (smoothed: 25 um noise differentiated)
    from dampnet.data.preprocess import moving_average

    d = moving_average(np.gradient(r.channels["displacement"], r.time), 51)
    assert np.corrcoef(d, r.channels["velocity"])[0, 1] > 0.99


def _bits(a):
    return np.asarray(a, dtype=np.float64).view(np.int64)


@pytest.mark.parametrize("effects", [[]] + [[name] for name in EFFECTS] + [list(EFFECTS)],
                         ids=lambda e: "+".join(e) or "none")
def test_stepwise_float_path_gives_the_context_path_bit_for_bit(effects):
    """TruthDamper.step's float path (effects' prepare_1 / force_1) against its Context path
    (1-element arrays, prepare_step / force_step): the same force, bit for bit, over random
    inputs: velocities through zero and the shims' crack, voltages on and between Table 2's
    breakpoints and outside it, temperatures given or not, every effect of the registry."""
    rng = np.random.default_rng(7)
    n = 4000
    x = rng.uniform(-0.03, 0.03, n)
    x[::50] = -(P.stroke_m / 2 - 0.004)                          # in the bump stop's travel
    v = rng.normal(0, 0.4, n) * rng.choice([1e-3, 1.0], n)
    v[::37] = 0.0
    volts = np.array(P.controller_voltage_v)
    u = np.where(rng.random(n) < 0.3, rng.choice(volts, n), rng.uniform(-1.0, 6.0, n))
    temp = rng.uniform(10, 90, n)
    for dt, temperature in ((2e-4, temp), (1e-3, None)):
        fast, slow = TruthDamper(effects=effects), TruthDamper(effects=effects)
        slow._floats = False
        assert fast._floats
        for k in range(n):
            t = None if temperature is None else temperature[k]
            a, b = fast.step(dt, x[k], v[k], u[k], t), slow.step(dt, x[k], v[k], u[k], t)
            assert type(a) is float and _bits(a) == _bits(b), (k, a, b)


def test_controller_current_of_one_float_is_np_interp_bit_for_bit():
    from dampnet.rig.truth import _controller_current_1
    rng = np.random.default_rng(3)
    volts = np.array(P.controller_voltage_v)
    xs = np.concatenate([volts, np.nextafter(volts, -np.inf), np.nextafter(volts, np.inf),
                         rng.uniform(-1, 6, 20000), [np.nan, -np.inf, np.inf, -0.0]])
    xp, fp = tuple(P.controller_voltage_v), tuple(P.controller_current_a)
    got = np.array([_controller_current_1(float(a), xp, fp) for a in xs])
    np.testing.assert_array_equal(_bits(got), _bits(controller_current(xs, P)))


def test_an_effect_without_float_forms_takes_the_context_path():
    from dampnet.rig.effects import GasSpring

    class Doubled(GasSpring):          # writes a force law, not its float form
        def force(self, ctx):
            return 2.0 * super().force(ctx)

    d = TruthDamper(effects=[Doubled()])
    assert not d._floats
    ref = truth_force(np.array([0.01]), np.array([0.2]), np.array([2.0]), dt=1e-3, effects=[Doubled()])
    assert d.step(1e-3, 0.01, 0.2, 2.0) == pytest.approx(ref[0], rel=1e-12)
