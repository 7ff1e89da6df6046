"""Training-envelope coverage (dampnet.envelope, dampnet.envelope.coverage): the joint measure against a
brute-force computation, a trajectory inside the training cloud, the quarter-car impulse far
outside it, per-input shares against a direct count, a model directory without an envelope, and
the JSON fields of simulate, study and vehicle. Quick plan, few epochs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.envelope.coverage import EXTRAPOLATED_SHARE, coverage, quarter_car_inputs
from dampnet.envelope import ENVELOPE_JSON, ENVELOPE_NPZ, build_envelope, load_envelope, training_samples
from dampnet.features import feature_matrix
from dampnet.sim.calibration import damping_levels
from dampnet.sim.dampers import load_spec, neural_spec
from dampnet.sim.roads import impulse
from dampnet.sim.quarter_car.runs import simulate
from dampnet.sim.vehicle import Controller


@pytest.fixture(scope="module")
def trained(quick_envelope_model):
    return quick_envelope_model


def test_envelope_files_and_nearest_distance_against_brute_force(trained):
    model, env = trained["model"], trained["env"]
    d = trained["root"] / "model"
    assert (d / ENVELOPE_NPZ).is_file() and (d / ENVELOPE_JSON).is_file()
    loaded, note = load_envelope(d, model)
    assert loaded is not None and "joint" in note
    np.testing.assert_array_equal(loaded.points, env.points)
    assert loaded.threshold == env.threshold > 0
    # the training samples: the model's sat range, scaled into [-1, 1]
    X = training_samples(model, trained["split"])
    np.testing.assert_allclose(X.min(0), model.sat_lo, atol=1e-9)
    np.testing.assert_allclose(X.max(0), model.sat_hi, atol=1e-9)
    assert np.all(np.abs(env.points) <= 1 + 1e-9)
    # nearest distances against numpy, in the model's own scaling
    rng = np.random.default_rng(1)
    q = rng.uniform(model.sat_lo * 1.5, model.sat_hi * 1.5, size=(300, model.n_inputs))
    s = (q - model.in_offset) * model.in_gain + model.in_ymin
    brute = np.sqrt(((s[:, None, :] - env.points[None, :, :]) ** 2).sum(-1)).min(1)
    np.testing.assert_allclose(loaded.distance(q), brute, rtol=1e-12, atol=1e-12)
    # the threshold is what the JSON says: factor x percentile of the points' own NN distances
    pts = env.points
    nn = np.array([np.sort(np.sqrt(((pts - p) ** 2).sum(1)))[1] for p in pts[::7]])
    meta = json.loads((d / ENVELOPE_JSON).read_text())
    assert meta["threshold"] == pytest.approx(meta["factor"] * meta["nn_percentile_value"])
    assert np.percentile(nn, 50) == pytest.approx(meta["nn_median"], rel=0.3)
    # a bounded subsample
    small = build_envelope(model, X, max_points=500)
    assert small.points.shape == (500, 3) and small.params["n_training"] == X.shape[0]


def test_trajectory_inside_training_cloud_is_not_extrapolated(trained):
    model, env = trained["model"], trained["env"]
    # the training tests at the full 5 kHz rate: between the stored (decimated) samples
    X = np.concatenate([feature_matrix([t], model.features, model.feature_params) for t in trained["split"].train.tests])
    cov = coverage(model, X, env, dt=2e-4)
    assert cov["outside"]["share_time"] < 0.005
    assert cov["joint"]["share_steps_outside"] < 0.005
    assert not cov["extrapolated"] and cov["verdict"].startswith(("within", "mostly within"))


def test_impulse_is_extrapolated_and_shares_match_a_direct_count(trained):
    model, env = trained["model"], trained["env"]
    spec = neural_spec(model, envelope=env)
    lv = damping_levels(spec)
    run = simulate(spec, impulse(), None, Controller(kind="passive", u_passive=lv["low"]))
    cov = run["coverage"]
    assert cov["extrapolated"] and cov["verdict"].startswith("extrapolated: the model was outside its training data")
    # measured 0.11 (quick plan, 30 epochs; 0.20 with the rest points at 0 N): how long the response
    # stays outside depends on how the model damps it, while the excursion itself grows (below)
    assert cov["outside"]["share_time"] > 2 * EXTRAPOLATED_SHARE
    assert cov["worst_excursion"]["ranges"] > 2
    assert set(cov["outside"]["mostly"]) <= {"velocity", "acceleration"}
    # per-input shares against a direct count of the recorded inputs
    X = run["arrays"]["features"]
    assert X.shape == (len(run["arrays"]["t"]), 3)
    for i, f in enumerate(model.features):
        direct = np.mean((X[:, i] < model.sat_lo[i]) | (X[:, i] > model.sat_hi[i]))
        assert cov["inputs"][f]["share_steps_outside"] == pytest.approx(direct, abs=1e-12)
        assert cov["inputs"][f]["share_time_outside"] == pytest.approx(direct, abs=1e-9)
        width = model.sat_hi[i] - model.sat_lo[i]
        worst = np.max(np.maximum(np.maximum(model.sat_lo[i] - X[:, i], X[:, i] - model.sat_hi[i]), 0)) / width
        assert cov["inputs"][f]["worst_excursion_ranges"] == pytest.approx(worst)
    far = env.distance(X) > env.threshold
    assert cov["joint"]["share_steps_outside"] == pytest.approx(far.mean())
    any_range = np.any((X < model.sat_lo) | (X > model.sat_hi), axis=1)
    assert cov["outside"]["share_steps"] == pytest.approx(np.mean(any_range | far))
    np.testing.assert_array_equal(quarter_car_inputs(model, run["arrays"]), X)


def test_model_dir_without_envelope_reports_ranges_only(trained, tmp_path, capsys):
    spec = load_spec(str(trained["root"] / "model_old"))
    assert spec.meta["envelope"] is None and "no envelope.npz" in spec.meta["envelope_note"]
    out = tmp_path / "sim"
    assert main(["simulate", str(trained["root"] / "model_old"), "--road", "impulse", "--damping", "low",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "no joint envelope" in text and "extrapolated" in text
    m = json.loads((out / "metrics.json").read_text())
    assert m["coverage"]["joint"] is None and m["coverage"]["envelope"] == "ranges only"
    assert m["extrapolated"] is True and (out / "coverage.png").is_file()


def test_json_fields_of_simulate_study_and_vehicle(trained, tmp_path, capsys):
    root = trained["root"]
    out = tmp_path / "sim"
    assert main(["simulate", str(root / "model"), "--road", "impulse", "--damping", "low", "--out", str(out)]) == 0
    assert "coverage of neural" in capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    assert m["extrapolated"] is True and m["coverage"]["envelope"] == "joint"
    for key in ("inputs", "outside_ranges", "joint", "outside", "worst_excursion", "verdict", "extrapolated"):
        assert key in m["coverage"], key
    assert (out / "coverage.png").is_file()
    # a damper that is not a model: no coverage, no stale plot
    assert main(["simulate", "linear:1500", "--road", "impulse", "--out", str(out), "--force"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert "coverage" not in m and not (out / "coverage.png").exists()

    out = tmp_path / "study"
    assert main(["study", str(root / "model"), str(root / "data"), "--quick", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Coverage: share of the run's time outside the training envelope" in text
    res = json.loads((out / "study.json").read_text())
    assert set(res["coverage"]["impulse"]["low"]) == {"neural"}     # neural models only
    assert res["coverage"]["impulse"]["low"]["neural"]["extrapolated"] is True
    assert res["extrapolated"]["neural"]["any"] is True
    assert "impulse low" in res["extrapolated"]["neural"]["extrapolated"]
    assert (out / "coverage_neural.png").is_file()

    out = tmp_path / "vehicle"
    assert main(["vehicle", str(root / "model"), "--test", "bsst", "--out", str(out)]) == 0
    assert "coverage of neural" in capsys.readouterr().out
    m = json.loads((out / "metrics.json").read_text())
    assert isinstance(m["extrapolated"], bool) and m["coverage"]["envelope"] == "joint"
    assert set(m["coverage"]["corners"]) == {"fl", "fr", "rl", "rr"}
    assert m["coverage"]["steps"] == 4 * len(np.load(out / "run.npz")["t"])
    assert (out / "coverage.png").is_file()
