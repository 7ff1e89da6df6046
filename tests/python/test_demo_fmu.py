"""The demo's FMU stage (dampnet.demo.fmucheck) on models the demo's own run does not cover:
a model with derived-feature states (control lag, velocity lag, Dahl friction), whose forces
FMPy records one step late with the states advanced over that step; a model the FMU refuses;
no fmpy. The demo's run itself (test_demo.py) checks the stage on the improved model."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import loop_helpers
from dampnet import features
from dampnet.demo import fmucheck, report
from dampnet.rig import generate
from loop_helpers import random_model

STATEFUL = ["velocity", "acceleration", "voltage_lag", "velocity_lag", "friction_state", "displacement"]
PARAMS = {"control_lag_tau_s": 0.004, "velocity_lag_tau_s": 0.002, "friction_presliding_m": 0.0005}


@pytest.fixture(scope="module")
def rig_tests():
    """Two quick-plan rig tests (1 and 3 Hz at 5 V) whose control steps from 0 V at 0.1 s, so
    the control lag moves inside the stage's 0.5 s window."""
    ds = generate("quick", seed=0, progress=False)
    out = []
    for t in ds.tests:
        if t.control_nominal == 5.0 and t.frequency_hz in (1.0, 3.0):
            u = np.where(t.time - t.time[0] < 0.1, 0.0, t.control)
            out.append(t.copy(channels={**t.channels, "voltage": u}))
    return out


def test_stateful_model_matches_fmpy_to_1e9(rig_tests, tmp_path):
    model = random_model(STATEFUL, hidden=9, seed=4, feature_params=PARAMS,
                         terms=[{"kind": "bump_stop", "params": [0.01, 2e5, 1.5]}])
    res = fmucheck.check_fmu(model, rig_tests, tmp_path / "m" / "damper.fmu", tmp_path / "fig" / "fmu.png")
    assert "skipped" not in res, res
    assert res["fmi_version"] == "2.0" and (tmp_path / "m" / "damper.fmu").is_file()
    assert res["match"] and res["max_abs_diff_n"] <= 1e-9 and res["tolerance_n"] == 1e-9
    assert res["samples"] == 2501 and res["force_range_n"] > 100.0 and res["runtime_status_ok"]
    assert (tmp_path / "fig" / "fmu.png").stat().st_size > 10_000
    # the stage picked the test with the widest measured force range in the window (the 3 Hz one)
    assert res["test"] == max(rig_tests, key=lambda t: np.ptp(t.channels["force"][:2501])).test_id

    # without an envelope the FMU flags the training ranges only, as the runtime's ranges do
    assert res["envelope_flags"]["match"] and not res["envelope_flags"]["grid"]

    # the comparison is not vacuous: the states FMPy reads (held over its late step) are not
    # the loop's committed ones, so the loop's forces merely shifted one sample differ
    sig = fmucheck.rig_signals(model, next(t for t in rig_tests if t.test_id == res["test"]))
    f_loop, f_fmpy, _ = fmucheck.runtime_forces(model, sig)
    assert np.max(np.abs(f_fmpy[1:] - f_loop[:-1])) > 1.0


def test_envelope_flags_of_the_fmu_equal_the_runtime_check(rig_tests, tmp_path):
    """With the model's envelope (here built from the 1 Hz test's inputs alone), the FMU's
    envelope_flags on the 3 Hz test equal dampnet.envelope.grid's flags of the inputs FMPy's
    record has (states held over its late step), with samples both inside and outside."""
    from dampnet.envelope import build_envelope
    from dampnet.envelope.grid import runtime_flags
    from dampnet.features import feature_matrix

    model = random_model(STATEFUL, hidden=9, seed=4, feature_params=PARAMS)
    slow = next(t for t in rig_tests if t.frequency_hz == 1.0)
    env = build_envelope(model, feature_matrix([slow], model.features, model.feature_params))
    res = fmucheck.check_fmu(model, rig_tests, tmp_path / "damper.fmu", tmp_path / "fmu.png", envelope=env)
    ef = res["envelope_flags"]
    assert ef["grid"] and ef["match"] and 0.05 < ef["share_flagged"] < 0.95, ef
    sig = fmucheck.rig_signals(model, next(t for t in rig_tests if t.test_id == res["test"]))
    flags = runtime_flags(env, fmucheck.fmpy_inputs(model, sig))
    assert np.mean(flags != 0) == pytest.approx(ef["share_flagged"])
    html = report._fmu_section(tmp_path, {**res, "path": "damper.fmu", "figure": "fmu.png"})
    assert "envelope_flags" in html and "the same flags" in html


def test_a_model_the_fmu_refuses_is_reported_not_raised(tmp_path, monkeypatch):
    """A feature only Python knows: build_damper_fmu raises FmuError; the stage says why."""
    features.register_feature("pressure_x", "Pa", "pressure_x")
    try:
        monkeypatch.setitem(loop_helpers.RANGES, "pressure_x", (0.0, 1e6))
        monkeypatch.setitem(loop_helpers.UNITS, "pressure_x", "Pa")
        model = random_model(["velocity", "pressure_x"])
        res = fmucheck.check_fmu(model, [], tmp_path / "damper.fmu", tmp_path / "fmu.png")
    finally:
        features.unregister_feature("pressure_x")
    assert "pressure_x" in res["skipped"] and "path" not in res
    assert not (tmp_path / "damper.fmu").exists() and not (tmp_path / "fmu.png").exists()
    html = report._fmu_section(tmp_path, res)
    assert "Not checked" in html and "pressure_x" in html and "<img" not in html


def test_without_fmpy_the_fmu_is_built_and_the_check_skipped(rig_tests, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "fmpy", None)  # `import fmpy` raises ImportError
    model = random_model(["velocity", "acceleration", "voltage"], hidden=5, seed=1)
    res = fmucheck.check_fmu(model, rig_tests, tmp_path / "damper.fmu", tmp_path / "fmu.png")
    assert res["skipped"] == fmucheck.NO_FMPY == "fmpy is not installed: pip install fmpy"
    assert (tmp_path / "damper.fmu").is_file() and not (tmp_path / "fmu.png").exists()
    html = report._fmu_section(tmp_path, {**res, "path": "damper.fmu"})
    assert "fmpy is not installed" in html and "damper.fmu" in html
