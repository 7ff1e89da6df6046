"""Quarter-car runs: the runtime's loop vs the Python reference loop (the test oracle) vs scipy, truth vs
neural, skyhook, bad input."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy.signal import lsim

from dampnet.sim.dampers import DamperSpec, lookup_spec, neural_spec, truth_spec
from dampnet.sim.quarter_car.reference_loop import LinearDamper, reference_damper, run
from dampnet.sim.roads import RoadError, Road, iso8608, thesis_rough_road
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.vehicle import Controller, LoopError, Vehicle


def reference_run(spec, road, speed, ctrl, veh=None):
    """The same run in the Python reference loop (the oracle)."""
    veh = veh or Vehicle()
    s = road.sample(veh.dt, speed)
    return run(reference_damper(spec), s.z, s.zdot, veh, ctrl)



def lsim_quarter_car(z, t, c, ms=700.0, mu=40.0, ks=15e3, kt=200e3):
    a = np.array([[0, 1, 0, 0], [-ks / ms, -c / ms, ks / ms, c / ms], [0, 0, 0, 1],
                  [ks / mu, c / mu, -(ks + kt) / mu, -c / mu]])
    b = np.array([[0], [0], [0], [kt / mu]])
    return lsim((a, b, np.eye(4), np.zeros((4, 1))), z, t)[1]


def test_python_loop_matches_scipy_for_a_linear_damper():
    s = thesis_rough_road().sample(1e-3, speed=20.0)
    r = run(LinearDamper(1500.0), s.z, s.zdot, Vehicle(dt=1e-3))
    y = lsim_quarter_car(s.z, s.t, 1500.0)
    # Force held over each 1 ms step (the runtime's per-step mode): first order in dt; 1 %.
    assert np.max(np.abs(r["z_s"] - y[:-1, 0])) < 0.01 * np.max(np.abs(y[:, 0]))
    assert np.max(np.abs(r["z_us"] - y[:-1, 2])) < 0.01 * np.max(np.abs(y[:, 2]))


@pytest.mark.parametrize("control,u_tau_s", [("passive", 0.0), ("skyhook_onoff", 0.0), ("skyhook_onoff", 0.005),
                                             ("skyhook_continuous", 0.005), ("groundhook_onoff", 0.005),
                                             ("groundhook_continuous", 0.005)])
def test_python_loop_is_the_runtime_loop_for_linear_and_lookup(control, u_tau_s):
    from dampnet.evaluation.lookup import LookupTable

    table = LookupTable(velocities=[-1.0, -0.1, 0.0, 0.1, 1.0], voltages=[0.0, 5.0],
                        forces=[[-1500, -400, 0, 700, 3000], [-600, -150, 0, 200, 900]])
    road = thesis_rough_road()
    for spec in (DamperSpec("lin", "linear", 1500.0), lookup_spec(table)):
        ctrl = Controller(kind=control, u_tau_s=u_tau_s)
        a = simulate(spec, road, 20.0, ctrl)["arrays"]
        b = reference_run(spec, road, 20.0, ctrl)
        for k in ("z_s", "z_us", "acc_s", "force", "u"):
            np.testing.assert_allclose(a[k], b[k], rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(b[k]))))


@pytest.mark.parametrize("control", ["passive", "skyhook_onoff"])
def test_python_loop_is_the_runtime_loop_for_derived_features(control):
    """A model on the lagged control, lagged velocity and friction state (and displacement):
    the Python reference loop's feature states are the runtime's, to rounding."""
    from loop_helpers import random_model

    params = {"control_lag_tau_s": 0.02, "velocity_lag_tau_s": 0.002, "friction_presliding_m": 5e-4}
    model = random_model(["velocity", "voltage_lag", "velocity_lag", "friction_state", "displacement"],
                         seed=7, feature_params=params, force_range=800.0)
    spec = neural_spec(model)
    road = thesis_rough_road()
    ctrl = Controller(kind=control)
    veh = Vehicle(accel_feature="explicit")
    a = simulate(spec, road, 20.0, ctrl, vehicle=veh)["arrays"]
    b = reference_run(spec, road, 20.0, ctrl, veh)
    if control == "skyhook_onoff":
        assert np.ptp(a["u"]) > 0  # the control moves, so its lag matters
    for k in ("z_s", "z_us", "acc_s", "force", "u"):
        np.testing.assert_allclose(a[k], b[k], rtol=0, atol=1e-9 * max(1.0, np.max(np.abs(b[k]))))


# A rig plan that covers what the rough road asks of the damper: band-limited random
# displacement (0.5-15 Hz), 8 s per test. The quick plan's
# sines (0.25-3 Hz, 1 inch) reach only |a| < 9 m/s^2 with a = -w^2 x tied to the position;
# the road drives |a| above that 44-62 % of the time at low damping, and a model trained
# there extrapolates (its dF/da along the road: median 0-25 kg, up to 400 kg, and below
# -1/k in 1.6-9.6 % of the samples, so that the coupled a = a_free - k F(a) has several
# roots): 6-19 % off with either acceleration scheme (explicit +18.5/+8.1/+14.9/+6.2 %,
# implicit +18.6/+9.7/+12.9/+6.4 % at 10 low/high, 20 low/high).
# Voltages: skyhook drives every voltage between the ends, so the model trains on eight of
# them, on Table 2's breakpoints (denser below 2.25 V, where the damping at low speed changes
# fastest with the voltage), nothing held out. A model trained on 0 and 5 V only (the earlier
# plan, 2.25 V held out) tracks passive runs within 1.2 % but is 150-250 % off under continuous
# skyhook. Amplitudes 2, 5 and 12 mm RMS: the road's damper velocity RMS is 0.09-0.14 m/s at
# 0 V and 0.19-0.26 m/s at 5 V; the 5 and 12 mm tests give 0.28 and 0.66 m/s, so 2 mm
# (about 0.11 m/s) covers the stiff setting's slow strokes. 24 tests, LM training about 12 s.
ROAD_PLAN = dict(name="road", frequencies_hz=[1.0], amplitudes_m=[0.002, 0.005, 0.012],
                 voltages_v=[0.0, 0.5, 1.0, 1.5, 2.25, 3.0, 4.0, 5.0], excitation="random",
                 band_hz=[0.5, 15.0], duration_s=8.0, samples=10)


@pytest.fixture(scope="module")
def rig_models():
    import time

    from dampnet.rig import Plan, generate
    from dampnet.evaluation.lookup import fit_lookup
    from dampnet.training.pipeline import train_dataset

    ds = generate(Plan(**ROAD_PLAN), seed=0)
    t0 = time.perf_counter()
    model, _, _ = train_dataset(ds, algorithm="lm", max_epochs=200, seed=0, holdout_voltage=None)
    print(f"fixture training: {time.perf_counter() - t0:.1f} s")
    return neural_spec(model), lookup_spec(fit_lookup(generate("quick", seed=0))), truth_spec()


@pytest.fixture(scope="module")
def rough_runs(rig_models):
    from dampnet.sim.calibration import continuous_skyhook, damping_levels, semi_active

    neural, _, truth = rig_models
    road = thesis_rough_road()
    # One controller for both dampers, calibrated on the truth (dampnet.sim.calibration.continuous_skyhook:
    # c_sky = 2 sqrt(k_s m_s) / sqrt(2), c_min / c_max = the truth's equivalent damping at 5 / 0 V),
    # both laws with the study's 5 ms command filter.
    cont = continuous_skyhook(truth, damping_levels(truth))
    onoff = semi_active("skyhook_onoff", damping_levels(truth))
    assert cont.u_tau_s == onoff.u_tau_s == 0.005
    out = {}
    for spec in (neural, truth):
        lv = {"high": 0.0, "low": 5.0}
        for speed in (10.0, 20.0):
            for level, u in lv.items():
                r = simulate(spec, road, speed, Controller(kind="passive", u_passive=u))
                out[(spec.name, speed, level)] = r["metrics"]["acc_rms_m_s2"]
            r = simulate(spec, road, speed, onoff)
            out[(spec.name, speed, "skyhook_onoff")] = r["metrics"]["acc_rms_m_s2"]
            r = simulate(spec, road, speed, cont)
            out[(spec.name, speed, "skyhook_continuous")] = r["metrics"]["acc_rms_m_s2"]
            r = simulate(spec, road, speed, replace(cont, u_tau_s=0.0))
            out[(spec.name, speed, "skyhook_continuous_unfiltered")] = r["metrics"]["acc_rms_m_s2"]
    print("rough road acc RMS:", json.dumps({f"{n}_{v:g}_{k}": round(a, 4) for (n, v, k), a in out.items()}))
    return out


def test_rig_damper_levels(rig_models):
    from dampnet.sim.calibration import damping_levels

    assert damping_levels(rig_models[2]) == {"low": 5.0, "high": 0.0}   # 0 V = valve closed = stiff
    assert damping_levels(rig_models[1]) == {"low": 5.0, "high": 0.0}


@pytest.mark.parametrize("law", ["skyhook_onoff", "skyhook_continuous"])
@pytest.mark.parametrize("name", ["truth", "neural"])
@pytest.mark.parametrize("speed", [10.0, 20.0])
def test_skyhook_lowers_acceleration_against_passive_high(rough_runs, name, speed, law):
    # Skyhook between the damper's own settings against passive at its high-damping setting
    # (the same damper), by a margin far above the neural model's error. Recorded (truth / neural,
    # m/s^2): passive high 0.942 / 0.931 at 10 m/s, 1.201 / 1.203 at 20 m/s; on-off skyhook
    # 0.658 / 0.651 and 0.899 / 0.899; continuous 0.485 / 0.484 and 0.699 / 0.704.
    assert rough_runs[(name, speed, law)] < 0.85 * rough_runs[(name, speed, "high")]


@pytest.mark.parametrize("name", ["truth", "neural"])
@pytest.mark.parametrize("speed", [10.0, 20.0])
def test_continuous_skyhook_lowers_acceleration_against_passive_low(rough_runs, name, speed):
    """Against passive *low* damping (5 V) the continuous law helps, a little (dampnet.sim.quarter_car.study's
    docstring: the soft setting is already above the best passive damping for acceleration RMS
    and a semi-active law can only add damping). On-off skyhook is above passive low.

    The command filter makes this a property of the model too: unfiltered, the law's jumps of
    control jolt the body, the truth gains only 0.8 / 0.9 % (10 / 20 m/s), and the neural
    model, whose force answers the acceleration spikes of those jumps, is +1.4 / +2.2 % above
    its passive low.
    Recorded (filtered, 5 ms): truth 0.4848 vs 0.4909 (-1.2 %) at 10 m/s,
    0.6994 vs 0.7108 (-1.6 %) at 20 m/s; neural 0.4839 vs 0.4933 (-1.9 %) and 0.7038 vs 0.7158
    (-1.7 %); with training seeds 1 and 2 the neural model gains 1.7-2.5 %. On-off: +26 to +34 %."""
    assert rough_runs[(name, speed, "skyhook_continuous")] < 0.995 * rough_runs[(name, speed, "low")]
    assert rough_runs[(name, speed, "skyhook_onoff")] > rough_runs[(name, speed, "low")]


def test_neural_tracks_truth_under_skyhook(rough_runs):
    # The model must cover the voltages between the ends: recorded -1.1 / +0.0 % (on-off) and
    # -0.2 / +0.6 % (continuous) at 10 / 20 m/s, +2.7 / +3.8 % under unfiltered continuous skyhook;
    # trained on 0 and 5 V only it was +150 / +250 % under continuous skyhook.
    for law in ("skyhook_onoff", "skyhook_continuous"):
        for speed in (10.0, 20.0):
            t = rough_runs[("truth", speed, law)]
            assert rough_runs[("neural", speed, law)] == pytest.approx(t, rel=0.03), (law, speed)


@pytest.mark.slow(reason="a diagnosis of the road model, a retraining with what it names and the runs under "
                         "skyhook: the loop end to end (42-50 s on 2 loaded cores)")
def test_diagnosed_compressibility_makes_the_model_track_the_truth_under_skyhook(rig_models, rough_runs):
    """Diagnose the road model, add what the diagnosis names, and the model follows the truth
    under continuous skyhook without a command filter (the hardest case: jumps of control)
    2-3x more closely (the rig's oil compressibility lags the hydraulic force by 2 ms; the
    acceleration input carries only its first-order part)."""
    from dampnet.rig import Plan, generate
    from dampnet.effects import additions
    from dampnet.diagnosis.run import diagnose
    from dampnet.sim.calibration import continuous_skyhook, damping_levels
    from dampnet.training.pipeline import train_dataset

    neural, _, truth = rig_models
    ds = generate(Plan(**ROAD_PLAN), seed=0)
    d = diagnose(neural.obj, ds, n_surrogates=19)
    assert d["verdict"] == "compressibility", [(c["effect"], c["score"]) for c in d["candidates"]]
    tau = d["candidates"][0]["parameters"]["tau_s"]
    assert 0.001 < tau < 0.004  # rig: 2 ms (recorded estimate 1.78 ms)
    add = additions("compressibility", d["candidates"][0]["parameters"])
    model, _, _ = train_dataset(ds, features=list(neural.obj.features) + add["features"],
                                feature_params=add["feature_params"], algorithm="lm", max_epochs=200,
                                seed=0, holdout_voltage=None)
    improved = neural_spec(model, "improved")
    cont = continuous_skyhook(truth, damping_levels(truth), u_tau_s=0.0)
    errs, befores = {}, {}
    for speed in (10.0, 20.0):
        t = rough_runs[("truth", speed, "skyhook_continuous_unfiltered")]
        errs[speed] = (simulate(improved, thesis_rough_road(), speed, cont)["metrics"]["acc_rms_m_s2"] - t) / t
        befores[speed] = (rough_runs[("neural", speed, "skyhook_continuous_unfiltered")] - t) / t
    print("model vs truth under unfiltered continuous skyhook, before / after:",
          {k: (round(100 * befores[k], 2), round(100 * v, 2)) for k, v in errs.items()})
    # recorded (10 / 20 m/s): +1.49 / +2.99 % before, +1.07 / +1.76 % after; with the thesis's 20 ms
    # moving-average acceleration (the default until issue 49's item 17) +2.7 / +3.8 % before, +0.7 /
    # +1.7 % after: the zero-phase acceleration took 20-45 % of the error before anything was added
    for speed in errs:
        assert abs(errs[speed]) < 0.8 * abs(befores[speed]), (speed, befores[speed], errs[speed])
        assert abs(errs[speed]) < 0.02


def test_neural_tracks_truth_on_the_rough_road(rough_runs, capsys):
    errs = {}
    for speed in (10.0, 20.0):
        for level in ("low", "high"):
            t = rough_runs[("truth", speed, level)]
            n = rough_runs[("neural", speed, level)]
            errs[f"{speed:g}_{level}"] = (n - t) / t
    print("neural vs truth acc RMS error:", json.dumps({k: round(100 * v, 2) for k, v in errs.items()}))
    # Recorded (ROAD_PLAN model, LM 200 epochs, runtime loop, implicit acceleration feature):
    # +0.50 % / -1.21 % at 10 m/s low/high, +0.70 % / +0.14 % at 20 m/s. (The earlier plan,
    # 0 and 5 V only: +0.99 / -1.20 / +0.77 / -0.16 %.)
    assert all(abs(e) < 0.03 for e in errs.values())


def test_neural_tracks_truth_on_the_impulse(rig_models):
    # the study's 50 mm, 50 ms raised-cosine bump, passive: recorded +0.8 / -0.2 % (low / high);
    # a model trained on the thesis's 1-inch sines is 25-40 % off here (the demo's study)
    from dampnet.sim.roads import impulse

    neural, _, truth = rig_models
    for u in (5.0, 0.0):
        ctrl = Controller(kind="passive", u_passive=u)
        t = simulate(truth, impulse(), None, ctrl)["metrics"]["acc_rms_m_s2"]
        assert simulate(neural, impulse(), None, ctrl)["metrics"]["acc_rms_m_s2"] == pytest.approx(t, rel=0.03), u


def test_nonsensical_inputs_get_clear_errors():
    road = iso8608("C", length_m=50.0)
    spec = DamperSpec("lin", "linear", 1500.0)
    with pytest.raises(LoopError, match=r"vehicle 'm_s' = -700.0 \(sprung mass \[kg\], > 0\)"):
        simulate(spec, road, 10.0, vehicle=Vehicle(m_s=-700.0))
    with pytest.raises((LoopError, RoadError), match="dt"):
        simulate(spec, road, 10.0, vehicle=Vehicle(dt=0.0))
    with pytest.raises(RoadError, match="shorter than one time step"):
        simulate(spec, Road("tiny", "spatial", [0.0, 0.001], [0.0, 0.0]), 10.0)
    with pytest.raises(RoadError, match="not finite"):
        Road("nan", "spatial", [0.0, 1.0, 2.0], [0.0, float("nan"), 0.0])
    with pytest.raises(LoopError, match="not finite"):
        run(LinearDamper(1.0), np.array([0.0, np.nan, 0.0]), np.zeros(3))
    with pytest.raises(LoopError, match="'kind': unknown name 'magic'"):
        simulate(spec, road, 10.0, Controller(kind="magic"))


def test_simulate_command_writes_arrays_metrics_and_plots(tmp_path, capsys):
    from dampnet.cli import main

    out = tmp_path / "run"
    assert main(["simulate", "linear:1500", "--road", "iso:B", "--speed", "15", "--out", str(out)]) == 0
    d = np.load(out / "run.npz")
    assert {"t", "z_s", "z_us", "acc_s", "force"} <= set(d.files)
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    assert {"acc_rms_m_s2", "acc_wk_rms_m_s2", "disp_peak_to_rms", "travel_rms_m", "travel_max_m",
            "tyre_load_rms_n"} <= set(m)
    assert (out / "time_history.png").stat().st_size > 1000
    assert main(["simulate", "linear:1500", "--road", "rough", "--dt", "0", "--out", str(tmp_path / "dt0")]) == 2
    assert "dt" in capsys.readouterr().err


def test_simulate_command_keeps_runs_and_filters_the_switching_laws(tmp_path, capsys):
    from dampnet.cli import main
    from dampnet.commands.simulate import COMMAND_TAU_S
    from dampnet.sim.calibration import SKYHOOK_COMMAND_TAU_S

    assert COMMAND_TAU_S == SKYHOOK_COMMAND_TAU_S
    out = tmp_path / "run"
    args = ["simulate", "truth", "--road", "bump", "--control", "skyhook_continuous", "--out", str(out)]
    assert main(args) == 0
    meta = json.loads((out / "metrics.json").read_text())
    ctrl = meta["controller"]
    # calibrated on the damper as in the study (the rig damper's soft / stiff ends, not the defaults)
    assert ctrl["u_tau_s"] == COMMAND_TAU_S and 1000 < ctrl["c_min"] < 2500 and ctrl["c_max"] > 4000
    assert "command filter 5 ms" in capsys.readouterr().out
    before = (out / "run.npz").read_bytes()
    assert main(args + ["--command-tau", "0"]) == 2               # an existing run is kept ...
    assert "refusing to overwrite" in capsys.readouterr().err
    assert (out / "run.npz").read_bytes() == before
    assert main(args + ["--command-tau", "0", "--force"]) == 0    # ... unless asked
    assert json.loads((out / "metrics.json").read_text())["controller"]["u_tau_s"] == 0.0
    assert not list(out.glob(".*"))                                  # no temporary files left
    sweep = ["simulate", "linear:1500", "--road", "sweep", "--out", str(out), "--force"]
    assert main(sweep) == 0 and (out / "transmissibility.png").is_file()
    assert main(args + ["--force"]) == 0 and not (out / "transmissibility.png").exists()  # not this run's
    assert main(args[:-2] + ["--command-tau", "-1", "--out", str(tmp_path / "bad")]) == 2
    assert "u_tau_s" in capsys.readouterr().err
