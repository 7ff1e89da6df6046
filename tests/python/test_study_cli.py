"""`dampnet study MODEL DATA` end to end on rig data: the chapter 5 tables for the neural
model, the lookup table fitted to DATA and the truth damper, with errors against the truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.data import write_dataset
from dampnet.rig import generate
from dampnet.modeldir import save_model_dir
from dampnet.training.pipeline import train_dataset

PLAN = {"name": "study-cli", "frequencies_hz": [0.5, 1.5, 3.0], "amplitudes_m": [0.0254],
        "voltages_v": [0.0, 1.0, 2.25, 3.0, 5.0], "samples": 1500}


@pytest.fixture(scope="module")
def model_and_data(tmp_path_factory):
    root = tmp_path_factory.mktemp("study")
    ds = generate(PLAN, seed=0)
    model, _, _ = train_dataset(ds, algorithm="lm", max_epochs=60, seed=0)
    save_model_dir(model, None, root / "model")
    write_dataset(ds, root / "data")
    return root


def test_study_command_tables_truth_errors_and_plots(model_and_data):
    root = model_and_data
    out = root / "out"
    assert main(["study", str(root / "model"), str(root / "data"), "--quick", "--out", str(out)]) == 0
    res = json.loads((out / "study.json").read_text())
    assert res["truth"] == "truth" and set(res["models"]) == {res["models"][0], "lookup", "truth"}
    neural = res["models"][0]
    for section in ("impulse", "sine_sweep", "rough_road", "skyhook"):
        assert res[section], section
        for case, by_model in res[section].items():
            assert set(res["models"]) <= set(by_model), (section, case)
            assert all(np.isfinite(m["acc_rms_m_s2"]) and m["acc_rms_m_s2"] > 0 for m in by_model.values())
    # the errors are (model - truth) / truth of the same case, recomputed here
    case = res["rough_road"]["10_low"]
    err = res["errors"]["rough_road"]["10_low"][neural]["acc_rms_m_s2"]
    truth = case["truth"]["acc_rms_m_s2"]
    assert err == pytest.approx((case[neural]["acc_rms_m_s2"] - truth) / truth, rel=1e-9)
    assert {"10_low", "10_high", "20_low", "20_high"} <= set(res["rough_road"])
    # both skyhook laws against both passive settings; the continuous law calibrated on the truth
    assert {f"{v}_{c}" for v in (10, 20) for c in ("skyhook_onoff", "skyhook_continuous", "passive_low",
                                                     "passive_high")} <= set(res["skyhook"])
    assert res["settings"]["skyhook"]["continuous"]["calibrated_on"] == "truth"
    text = (out / "study.txt").read_text()
    assert neural in text and "lookup" in text and "truth" in text
    assert len(list(out.glob("*.png"))) >= 6


def test_study_command_refuses_to_overwrite(model_and_data, capsys):
    root = model_and_data
    out = root / "out2"
    out.mkdir()
    (out / "study.json").write_text("{}")
    assert main(["study", str(root / "model"), "--quick", "--no-plots", "--out", str(out)]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
    assert (out / "study.json").read_text() == "{}"


def test_study_command_full_vehicle(model_and_data):
    """--vehicle: the chapter 5.2 comparison of the same models (the neural model, the lookup
    table, the truth) in the bounce sweep and the lane change, each damping, with the errors
    against the truth, in study.json and study.txt."""
    root = model_and_data
    out = root / "out_vehicle"
    assert main(["study", str(root / "model"), str(root / "data"), "--quick", "--no-plots", "--vehicle",
                 "--out", str(out)]) == 0
    res = json.loads((out / "study.json").read_text())
    veh = res["vehicle"]
    for test in ("bsst_heave", "dlc"):
        for d in ("low", "high", "skyhook"):
            assert set(veh["results"][test][d]) == set(res["models"])
            assert set(veh["errors"][test][d]) == set(res["models"]) - {"truth"}
    dlc = veh["results"]["dlc"]["low"]["truth"]
    assert 3.0 < dlc["a_y_peak_m_s2"] < 12.0 and dlc["cones"] == 30
    assert "full vehicle (chapter 5.2)" in (out / "study.txt").read_text()
