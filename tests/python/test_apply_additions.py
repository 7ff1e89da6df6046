"""The diagnose -> add effect -> retrain step has one home, dampnet.training.pipeline.apply_additions:
`dampnet train --add EFFECT --diagnosis FILE` and the demo's improve stage (its request,
dampnet.demo.run.improved_request) give the same training settings for the same diagnosis (its parameters, not re-estimated ones); `--add`
alone estimates the parameters from the data; bad diagnosis input is a one-line error."""

from __future__ import annotations

import json

import pytest

from dampnet.cli import build_parser, main
from dampnet.commands.training_options import training_kwargs
from dampnet.data import load_dataset, write_dataset
from dampnet.demo.run import improved_request
from dampnet.diagnosis.estimate import estimate_parameters
from dampnet.diagnosis.run import diagnose
from dampnet.model import MlpModel
from dampnet.rig import generate
from dampnet.recipes.training import plan
from dampnet.training.pipeline import apply_additions, train_dataset

PLAN = {"name": "tiny", "frequencies_hz": [0.5, 2.0, 3.0], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 2.25, 5.0], "samples": 800}
ADDED = ("compressibility", "friction")  # testable on this plan, with parameters the additions read


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A small dataset on disk, a quickly trained model and its diagnosis (as dict and JSON file)."""
    root = tmp_path_factory.mktemp("additions")
    write_dataset(generate(PLAN, effects=["friction"], seed=2), root / "data")
    ds = load_dataset(root / "data")  # what the CLI sees
    model, _, _ = train_dataset(ds, max_epochs=10, decimate=4, seed=0)
    diag = diagnose(model, ds, n_surrogates=4)
    (root / "d.json").write_text(json.dumps(diag, indent=1))  # as `dampnet diagnose --json` writes it
    return root, ds, model, diag


def _cli_settings(root, ds, *argv):
    args = build_parser().parse_args(["train", str(root / "data"), "--out", str(root / "unused"), *argv])
    kw, added = training_kwargs(args, ds)
    return kw, added


def _param(diag, effect):
    return next(c for c in diag["candidates"] if c["effect"] == effect)["parameters"]


@pytest.mark.parametrize("effect", ADDED)
def test_cli_and_demo_give_the_same_additions_for_the_same_diagnosis(case, effect):
    root, ds, model, diag = case
    kw, added = _cli_settings(root, ds, "--add", effect, "--diagnosis", str(root / "d.json"))
    demo_plan = plan(ds, improved_request(model, diag, effect, seed=0))   # the demo's improve stage
    demo, adds = demo_plan.kw, demo_plan.added[0]
    for key in ("features", "terms", "feature_params"):
        assert kw[key] == demo[key], key
    assert kw["features"] == [*model.features, *adds["features"]]
    # the diagnosis's own estimate, not a re-estimate from the data
    p = _param(diag, effect)
    (key, value), = kw["feature_params"].items()
    expected = p["tau_s"] if effect == "compressibility" else p["presliding_length_mm"] / 1000.0
    assert value == expected and added[0]["parameters_from"] == "diagnosis"


def test_add_without_diagnosis_estimates_from_the_data(case):
    root, ds, model, diag = case
    kw, added = _cli_settings(root, ds, "--add", "compressibility")
    assert kw["feature_params"] == {"velocity_lag_tau_s": estimate_parameters("compressibility", ds)["tau_s"]}
    assert added[0]["parameters_from"] == "estimated from the data"
    kw, added = _cli_settings(root, ds, "--add", "friction")  # no estimator: the catalogue's default
    assert kw["feature_params"] == {"friction_presliding_m": 0.2e-3} and added[0]["parameters_from"] == "catalogue defaults"


def test_train_with_a_diagnosis_writes_its_parameter_into_the_model(case, tmp_path):
    root, ds, model, diag = case
    out = tmp_path / "m"
    assert main(["train", str(root / "data"), "--out", str(out), "--add", "compressibility",
                 "--diagnosis", str(root / "d.json"), "--decimate", "20", "--max-epochs", "5", "--quiet",
                 "--valve", "off"]) == 0
    m = MlpModel.load(out)
    assert m.features[-1] == "velocity_lag"
    assert m.feature_params == {"velocity_lag_tau_s": _param(diag, "compressibility")["tau_s"]}


def test_apply_additions_merges_once_and_keeps_the_given_settings(case):
    root, ds, model, diag = case
    base = {"features": ["velocity", "acceleration", "voltage", "displacement"], "max_epochs": 7,
            "feature_params": {"velocity_lag_tau_s": 0.005}}
    out, add = apply_additions(base, ds, "gas_spring", diagnosis=diag)
    assert out["features"] == base["features"] and out["max_epochs"] == 7  # displacement not added twice
    assert out["feature_params"] == {"velocity_lag_tau_s": 0.005} and out["terms"] == []
    out, _ = apply_additions(out, ds, "friction", params={"presliding_length_mm": 0.5})
    assert out["features"][-1] == "friction_state"
    assert out["feature_params"] == {"velocity_lag_tau_s": 0.005, "friction_presliding_m": 0.5 / 1000.0}
    assert base["features"][-1] == "displacement"  # the caller's settings are not changed
    with pytest.raises(ValueError, match="not both"):
        apply_additions(base, ds, "friction", diagnosis=diag, params={})


def test_a_diagnosis_that_could_not_test_the_effect_is_refused(case):
    root, ds, model, diag = case
    d = json.loads(json.dumps(diag))
    for c in d["candidates"]:
        if c["effect"] == "friction":
            c.update(testable=False, parameters={}, note="no velocity history")
    with pytest.raises(ValueError, match="'friction' was not testable.*no velocity history"):
        apply_additions({}, ds, "friction", diagnosis=d)
    d["candidates"] = [c for c in d["candidates"] if c["effect"] != "friction"]
    with pytest.raises(ValueError, match="no entry for effect 'friction'"):
        apply_additions({}, ds, "friction", diagnosis=d)


@pytest.mark.parametrize("argv, fragments", [
    (["--diagnosis", "{d}"], ["--diagnosis", "--add EFFECT"]),
    (["--add", "friction", "--diagnosis", "{bad}"], ["bad.json", "line 1", "diagnosis JSON"]),
    (["--add", "friction", "--diagnosis", "{missing}"], ["missing.json", "cannot read"]),
    (["--add", "friction", "--diagnosis", "{other}"], ["--add friction", "other.json", "no 'candidates'"]),
    (["--add", "no_such_effect", "--diagnosis", "{d}"], ["no_such_effect", "expected one of"]),
])
def test_bad_diagnosis_input_is_one_line_and_exit_2(case, tmp_path, capsys, argv, fragments):
    root, ds, model, diag = case
    (tmp_path / "bad.json").write_text("{oops")
    (tmp_path / "other.json").write_text('{"format": "something-else"}')
    paths = {"d": root / "d.json", "bad": tmp_path / "bad.json", "missing": tmp_path / "missing.json",
             "other": tmp_path / "other.json"}
    argv = [a.format(**paths) for a in argv]
    rc = main(["train", str(root / "data"), "--out", str(tmp_path / "m"), "--quiet", *argv])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    for f in fragments:
        assert f in err, (f, err)
    assert not (tmp_path / "m").exists()
