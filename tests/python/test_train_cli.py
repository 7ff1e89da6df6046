"""`dampnet train` and dampnet.training.pipeline: model directory, hold-out, errors, reproducibility,
feature checks, hybrid terms; the thesis-plan accuracy floor and the noise floor."""

import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.data import DataError, write_dataset
from dampnet.rig import generate
from dampnet.model import MlpModel
from dampnet.training import nrmse
from dampnet.features import feature_matrix
from dampnet.training.pipeline import noise_floors, train_dataset
from dampnet.predict import predict_force
from dampnet.modeldir import save_model_dir
from dampnet.terms import terms_force

# Small but voltage-rich: the MLP has to interpolate to the held-out 2.25 V.
SMALL_PLAN = {"name": "small", "frequencies_hz": [0.5, 1.5, 3.0], "amplitudes_m": [0.0254],
              "voltages_v": [0.0, 1.0, 2.25, 3.0, 4.0, 5.0], "samples": 2500}


@pytest.fixture(scope="module")
def small_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("data") / "small"
    write_dataset(generate(SMALL_PLAN, seed=5), d)
    return d


@pytest.fixture(scope="module")
def trained(small_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("models") / "m"
    # --valve off: one training (the default's second, with a valve term, is test_valve_choice's);
    # --max-epochs 200: these tests check the directory, its metadata and a generalising model, not
    # convergence (BR's default 1,000 epochs took 18 s of the module's 66)
    rc = main(["train", str(small_dir), "--out", str(out), "--decimate", "20", "--quiet", "--seed", "1",
               "--valve", "off", "--max-epochs", "200"])
    assert rc == 0
    return out


def test_model_dir_holds_model_metrics_and_header(trained, small_dir):
    assert sorted(p.name for p in trained.iterdir()) == ["envelope.json", "envelope.npz", "metrics.json", "model.h",
                                                         "model.json"]
    model = MlpModel.load(trained)
    assert model.features == ["velocity", "acceleration", "voltage"]
    assert model.hidden == (30,) and model.activation == "tanh"
    meta = model.meta
    for key in ("algorithm", "settings", "training_time_s", "seed", "data", "metrics"):
        assert key in meta
    # the command's automatic algorithm: Bayesian regularisation on data this small
    assert meta["algorithm"] == "br" and meta["data"]["decimate"] == 20
    assert len(meta["data"]["holdout_tests"]) == 3 and meta["data"]["holdout_voltage"] == 2.25
    assert set(meta["data"]["holdout_tests"]).isdisjoint(meta["data"]["train_tests"])
    header = (trained / "model.h").read_text()
    assert "DN_MODEL_DESC_INIT" in header and model.model_id() in header
    metrics = json.loads((trained / "metrics.json").read_text())
    for key in ("nrmse", "rmse_n", "max_abs_error_n", "mean_pct_error"):
        assert key in metrics["holdout"]["overall"] and key in metrics["holdout_lookup"]["overall"]
    assert [r["frequency_hz"] for r in metrics["holdout"]["per_frequency"]] == [0.5, 1.5, 3.0]
    assert metrics["noise_floor"]["nrmse_range"] < metrics["noise_floor"]["nrmse_std"]
    # the hold-out error against the noise floor: RMSE over the noise's RMS, overall and per frequency
    hv, nf = metrics["noise_floor"]["holdout_vs_floor"], metrics["noise_floor"]
    assert hv["ratio"] == pytest.approx(metrics["holdout"]["overall"]["rmse_n"] / nf["rmse_n"], rel=1e-12)
    assert hv["ratio"] > 1.0  # the measured force carries the noise, so no model is below it
    # per frequency, from the held-out tests themselves: the floor's NRMSE is the noise's RMS over
    # that frequency's measured force range
    from dampnet.data import load_dataset

    ds = load_dataset(small_dir)
    held = [t for t in ds.tests if t.test_id in metrics["holdout_tests"]]
    for r, row in zip(hv["per_frequency"], metrics["holdout"]["per_frequency"]):
        forces = np.concatenate([t.channels["force"] for t in held if t.frequency_hz == row["frequency_hz"]])
        assert r["frequency_hz"] == row["frequency_hz"]
        assert r["floor_nrmse"] == pytest.approx(nf["rmse_n"] / np.ptp(forces), rel=1e-9)
        assert r["ratio"] == pytest.approx(row["rmse_n"] / nf["rmse_n"], rel=1e-12)


def test_model_json_round_trips(trained):
    d = json.loads((trained / "model.json").read_text())
    model = MlpModel.from_dict(d)
    assert json.loads(json.dumps(model.to_dict())) == d
    again = MlpModel.from_dict(json.loads(json.dumps(model.to_dict())))
    x = np.array([[0.1, 2.0, 1.5], [-0.3, -5.0, 4.0]])
    np.testing.assert_array_equal(again.predict(x), model.predict(x))


def test_holdout_prediction_generalises_and_beats_constant(trained, small_dir):
    """The 2.25 V tests were never seen; the MLP still predicts them far better than a constant."""
    metrics = json.loads((trained / "metrics.json").read_text())
    ho = metrics["holdout"]["overall"]
    assert ho["nrmse"] < 0.05
    assert metrics["training"]["nrmse"]["test"] < 0.02


def test_refuses_existing_dir_unless_force(trained, small_dir, capsys):
    before = (trained / "model.json").read_text()
    rc = main(["train", str(small_dir), "--out", str(trained), "--quiet", "--decimate", "50"])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("dampnet: error:") and "--force" in err and err.count("\n") == 1
    assert (trained / "model.json").read_text() == before


def test_force_replaces_atomically(tmp_path):
    X = np.random.default_rng(0).normal(size=(50, 3))
    from dampnet.training import fit

    m1, _ = fit(X, X[:, 0], features=["velocity", "acceleration", "voltage"], hidden=(3,), max_epochs=2)
    out = tmp_path / "m"
    save_model_dir(m1, {"a": 1}, out)
    with pytest.raises(FileExistsError):
        save_model_dir(m1, {"a": 2}, out)
    save_model_dir(m1, {"a": float("nan")}, out, force=True)
    assert json.loads((out / "metrics.json").read_text()) == {"a": None}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m"]  # no temporary leftovers


@pytest.mark.parametrize("argv, message", [
    (["--holdout-voltage", "1.1"], "nothing to hold out"),
    (["--terms", "[{oops"], "--terms: not valid JSON"),
    (["--features", "velocity,colour"], "unknown feature"),
    (["--features", "velocity,temperature"], "'temperature'"),
    (["--hidden", "3x"], "--hidden"),
    (["--add", "no_such_effect"], "no_such_effect"),
    (["--holdout-tests", "T999"], "T999"),
])
def test_bad_input_is_one_line_and_exit_2(small_dir, tmp_path, capsys, argv, message):
    rc = main(["train", str(small_dir), "--out", str(tmp_path / "m"), "--quiet", *argv])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert err.startswith("dampnet: error:") and message in err and err.count("\n") == 1
    assert not (tmp_path / "m").exists()


def test_missing_data_file_is_a_clean_error(tmp_path, capsys):
    rc = main(["train", str(tmp_path / "nope"), "--out", str(tmp_path / "m"), "--quiet"])
    assert rc == 2 and capsys.readouterr().err.startswith("dampnet: error:")


def test_same_seed_same_model_other_seed_differs():
    ds = generate(SMALL_PLAN, seed=2)
    kw = dict(decimate=50, hidden=(8,), max_epochs=20)
    a, _, _ = train_dataset(ds, seed=3, **kw)
    b, _, _ = train_dataset(generate(SMALL_PLAN, seed=2), seed=3, **kw)
    c, _, _ = train_dataset(ds, seed=4, **kw)
    assert a.model_id() == b.model_id()
    np.testing.assert_array_equal(a.w1, b.w1)
    assert a.model_id() != c.model_id()


def test_model_refuses_data_without_its_feature(tmp_path, capsys):
    thermal = generate("quick", effects=["thermal"], seed=0)
    model, _, _ = train_dataset(thermal, features=["velocity", "acceleration", "voltage", "temperature"],
                                decimate=50, hidden=(6,), max_epochs=10)
    assert model.features[-1] == "temperature" and model.units[-1] == "degC"
    plain = generate("quick", seed=0)
    with pytest.raises(DataError, match="'temperature'"):
        predict_force(model, plain.tests[0])
    # and through the CLI: one line, exit 2, naming the feature
    save_model_dir(model, {}, tmp_path / "m")
    write_dataset(plain, tmp_path / "plain")
    rc = main(["evaluate", str(tmp_path / "m"), str(tmp_path / "plain")])
    err = capsys.readouterr().err
    assert rc == 2 and "temperature" in err and err.count("\n") == 1


def test_rest_points_can_be_switched_off():
    ds = generate("quick", seed=0)
    on, info_on, _ = train_dataset(ds, decimate=50, hidden=(4,), max_epochs=2)
    off, info_off, _ = train_dataset(ds, decimate=50, hidden=(4,), max_epochs=2, rest_target="none")
    assert info_on.n_rest_points == int(np.ceil(0.01 * info_on.n_train)) and info_off.n_rest_points == 0
    assert on.meta["rest_force"]["target"] == "estimated" and on.meta["samples"]["rest_points"] > 0
    assert off.meta["rest_force"]["source"] == "no rest points" and off.meta["samples"]["rest_points"] == 0


def test_rest_points_sit_at_the_rig_damper_s_own_force_at_rest(small_dir, tmp_path, capsys):
    """The rig's damper pushes its gas force at rest (truth_force at v = 0, x = 0): by default the
    rest points' target is the damper's own force at rest, estimated within 5 N of the rig's truth,
    and the command says so. By default (valve "auto") the kept model is the hybrid here: the
    estimate is read from the measured force, not from what the valve term leaves (its steep bleed
    near v = 0 put it 24 N off)."""
    from dampnet.rig.truth import truth_force

    at_rest = float(truth_force(np.zeros(1), np.zeros(1), np.full(1, 2.25), dt=1e-3)[0])
    assert at_rest < -100.0       # a gas-charged damper: 0 N would contradict every sample near v = 0
    out = tmp_path / "m"
    rc = main(["train", str(small_dir), "--out", str(out), "--decimate", "20", "--hidden", "4",
               "--max-epochs", "2", "--algorithm", "lm"])
    printed = capsys.readouterr().out
    assert rc == 0
    meta = json.loads((out / "model.json").read_text())["meta"]
    assert meta["valve"]["used"], meta["valve"]     # the case the docstring's last sentence is about
    rest = meta["rest_force"]
    assert rest["source"] == "estimated" and abs(rest["force_N"] - at_rest) < 5.0, (rest, at_rest)
    assert rest["target"] == "estimated" and abs(rest["target_N"] - at_rest) < 5.0, (rest, at_rest)
    line = next(ln for ln in printed.splitlines() if ln.startswith("rest points: "))
    assert f"at {rest['target_N']:.1f} N (the damper's own force at rest: " in line, line


def test_rest_target_zero_and_none(small_dir, tmp_path, capsys):
    """--rest-target (the option every front end shares, dampnet.training.settings.OPTIONS): zero
    trains the rest points to the thesis's 0 N and still reports the estimate; none adds no rest
    points and prints no rest line; a word that is not a target is refused naming the choices."""
    from dampnet.rig.truth import truth_force

    at_rest = float(truth_force(np.zeros(1), np.zeros(1), np.full(1, 2.25), dt=1e-3)[0])
    args = ["--decimate", "20", "--hidden", "4", "--max-epochs", "2", "--algorithm", "lm", "--valve", "off"]
    rc = main(["train", str(small_dir), "--out", str(tmp_path / "zero"), *args, "--rest-target", "zero"])
    printed = capsys.readouterr().out
    assert rc == 0
    rest = json.loads((tmp_path / "zero" / "model.json").read_text())["meta"]["rest_force"]
    assert rest["target"] == "zero" and rest["target_N"] == 0.0 and abs(rest["force_N"] - at_rest) < 5.0
    line = next(ln for ln in printed.splitlines() if ln.startswith("rest points: "))
    assert (f"at 0.0 N (the thesis's 0 N; the damper's own force at rest: {rest['force_N']:.1f} N on average, "
            "estimated from") in line, line
    rc = main(["train", str(small_dir), "--out", str(tmp_path / "none"), *args, "--rest-target", "none"])
    printed = capsys.readouterr().out
    assert rc == 0 and "rest points: " not in printed
    meta = json.loads((tmp_path / "none" / "model.json").read_text())["meta"]
    assert meta["rest_force"]["source"] == "no rest points" and meta["samples"]["rest_points"] == 0
    with pytest.raises(SystemExit) as e:
        main(["train", str(small_dir), "--out", str(tmp_path / "m2"), "--rest-target", "measured"])
    assert e.value.code == 2 and "choose from 'estimated', 'zero', 'none'" in capsys.readouterr().err
    with pytest.raises(ValueError, match=r"rest_target \(--rest-target, .*\): expected one of estimated, zero, "
                                         r"none, got 'measured'"):
        train_dataset(generate("quick", seed=0), decimate=50, hidden=(4,), max_epochs=2, rest_target="measured")


def test_hybrid_position_poly_is_fitted_and_added_to_predictions(tmp_path):
    """Gas-spring data: the position polynomial takes the position-dependent force; the model's
    prediction is MLP + terms, and the terms survive model.json."""
    ds = generate(SMALL_PLAN, effects=["gas_spring"], seed=3)
    model, info, split = train_dataset(ds, terms=[{"kind": "position_poly"}], decimate=25,
                                       hidden=(10,), max_epochs=60)
    (term,) = model.terms
    assert term["kind"] == "position_poly" and len(term["params"]) == 4
    # the gas pushes the rod out (negative force), harder the further it is compressed (x < 0):
    # the force rises with x
    assert term["params"][1] > 0
    t = split.holdout.tests[0]
    X = feature_matrix([t], model.features)
    x = t.channels["displacement"]
    np.testing.assert_allclose(predict_force(model, t), model.predict(X) + terms_force(model.terms, x))
    held = split.holdout.tests
    pooled = nrmse(np.concatenate([predict_force(model, h) for h in held]), split.holdout.concat("force"))
    assert pooled < 0.05
    back = MlpModel.load(model.save(tmp_path / "model.json"))
    assert back.terms == json.loads(json.dumps(model.terms))
    np.testing.assert_allclose(predict_force(back, t), predict_force(model, t), rtol=1e-12)


def test_given_term_params_are_kept():
    ds = generate("quick", seed=0)
    terms = [{"kind": "position_poly", "params": [10.0, 0.0, 0.0, 0.0]}]
    model, _, _ = train_dataset(ds, terms=terms, decimate=50, hidden=(4,), max_epochs=3)
    assert model.terms[0]["params"] == [10.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize("algorithm", ["lm", "br", "scg", "adam"])
def test_each_algorithm_beats_a_constant_by_far(algorithm):
    ds = generate(SMALL_PLAN, seed=4)
    # Adam's epochs are its costliest (mini-batches): 50 reach 0.0115 against the bound's 0.0286
    # (0.0109 at 80), at a third of 150's time
    epochs = 50 if algorithm == "adam" else 150
    model, info, split = train_dataset(ds, algorithm=algorithm, decimate=25, max_epochs=epochs, seed=0)
    f = split.train_used.concat("force")
    const = nrmse(np.full_like(f, f.mean()), f)  # about 0.23 on sine tests
    assert info.metrics["test"] < 0.2 * const, (algorithm, info.metrics, const)


@pytest.mark.slow(reason="LM on the thesis plan's 180 tests, 120 epochs: the claim against the thesis's NRMSE "
                         "needs that plan (42-52 s on 2 loaded cores)")
def test_thesis_plan_lm_beats_the_thesis_and_approaches_the_noise_floor(record_property):
    """Default rig data (thesis plan, no effects), 2.25 V held out: LM's hold-out NRMSE must be
    at least as good as the thesis's 0.0339 and within 5x the noise floor (the same range
    definition) after 120 epochs; both figures are recorded in the test report. Measured (seed 0,
    every 25th sample): 0.00487 at 120 epochs (3.8x the floor of 0.00127, 22 s), 0.00376 at the
    default's 788 (140 s: the full-length training is the demo's and bench/'s, not the suite's)."""
    ds = generate("thesis", seed=0)
    model, info, split = train_dataset(ds, algorithm="lm", decimate=25, seed=0, max_epochs=120)
    preds = np.concatenate([predict_force(model, t) for t in split.holdout.tests])
    ho = nrmse(preds, split.holdout.concat("force"))
    floor = noise_floors(split.holdout)["nrmse_range"]
    record_property("holdout_nrmse", ho)
    record_property("noise_floor_nrmse_range", floor)
    print(f"thesis plan: LM hold-out NRMSE {ho:.5f}, noise floor {floor:.5f}, time {info.time_s:.1f} s")
    assert ho <= 0.0339
    assert floor < ho < 5 * floor


def test_model_improved_for_friction_and_compressibility_runs_in_the_runtime_loop(tmp_path):
    """`train --add friction --add compressibility` gives a model on friction_state and
    velocity_lag; its header carries their constants and `simulate` runs it in the C++ loop."""
    data = tmp_path / "fric"
    write_dataset(generate(SMALL_PLAN, effects=["friction"], seed=6), data)
    out = tmp_path / "m"
    rc = main(["train", str(data), "--out", str(out), "--add", "friction", "--add", "compressibility",
               "--decimate", "20", "--max-epochs", "40", "--quiet", "--control-prior", "0", "--valve", "off"])
    # without the control prior: the model this comparison was measured on. With it, this run, 4 % of
    # its time clamped up to 16 training ranges out, put the oracle's and the runtime's acceleration RMS
    # 0.4 % apart (issue 33's note: not yet understood)
    assert rc == 0
    model = MlpModel.load(out)
    assert {"friction_state", "velocity_lag"} <= set(model.features)
    assert model.feature_params["friction_presliding_m"] > 0 and model.feature_params["velocity_lag_tau_s"] > 0
    header = (out / "model.h").read_text()
    assert '"friction_presliding_m"' in header and '"velocity_lag_tau_s"' in header
    sim = tmp_path / "sim"
    assert main(["simulate", str(out), "--road", "bump", "--out", str(sim)]) == 0
    run = np.load(sim / "run.npz")
    assert np.all(np.isfinite(run["force"])) and np.ptp(run["force"]) > 100.0
    # the Python reference loop (the test oracle, its own feature-state updates) agrees
    from dampnet.sim.dampers import neural_spec
    from dampnet.sim.quarter_car.reference_loop import reference_damper
    from dampnet.sim.quarter_car.reference_loop import run as reference_loop
    from dampnet.recipes.roads import build as make_road
    from dampnet.sim.vehicle import Controller, Vehicle

    road, veh = make_road("bump", seed=0), Vehicle(dt=1e-3)
    s = road.sample(veh.dt, 10.0 if road.kind == "spatial" else None)
    ctrl = Controller(kind="passive", u_passive=float(run["u"][0]))  # the run's passive level
    py = reference_loop(reference_damper(neural_spec(model)), s.z, s.zdot, veh, ctrl)
    for key in ("acc_s", "force"):
        rms = lambda a: float(np.sqrt(np.mean(np.square(a))))  # noqa: E731
        assert rms(py[key]) == pytest.approx(rms(run[key]), rel=1e-4), key  # runtime float32 vs oracle float64: 1.4e-6 measured
    travel = lambda r: float(np.max(np.abs(r["z_s"] - r["z_us"])))  # noqa: E731
    assert travel(py) == pytest.approx(travel(run), rel=1e-4)  # measured: 54.55 mm both
