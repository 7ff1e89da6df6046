"""The error where the model guesses, on measured data (issue 53 item 3; dampnet.evaluation.regions):
the samples at rest are found where the damper stands still and nowhere else (a sine's reversal is
not rest; a record without a still stretch says the error at rest is not measured), the errors
placed on them are the ones reported, and "outside the envelope" is coverage()'s, step by step.
The default model (no training), hand-made tests and one real record. Cost: about 2 s."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.data import DynoTest
from dampnet.envelope import build_envelope
from dampnet.envelope.coverage import coverage, outside_shares, outside_steps
from dampnet.evaluation.regions import REST_MIN_S, at_rest_mask, region_errors, summary_lines
from dampnet.modeldir import default_model
from dampnet.predict import predict_force

DT = 1e-3


def held_sine(rest_s: float = 0.5, hz: float = 1.0, amp: float = 0.02, volts: float = 2.0, cycles: int = 2):
    """A test standing still for rest_s, then `cycles` sine cycles (velocity from the first sample at
    its peak, as a dyno started at speed), then still again for rest_s; (test, the true rest mask)."""
    n_rest, n_move = int(round(rest_s / DT)), int(round(cycles / hz / DT))
    t = np.arange(2 * n_rest + n_move) * DT
    x, v = np.zeros(t.size), np.zeros(t.size)
    tm = np.arange(n_move) * DT
    x[n_rest:n_rest + n_move] = amp * np.sin(2 * np.pi * hz * tm)
    v[n_rest:n_rest + n_move] = amp * 2 * np.pi * hz * np.cos(2 * np.pi * hz * tm)
    x[n_rest + n_move:] = x[n_rest + n_move - 1]
    rest = np.ones(t.size, dtype=bool)
    rest[n_rest:n_rest + n_move] = False
    test = DynoTest(test_id=f"held{volts:g}", time=t, frequency_hz=hz, amplitude_m=amp, control_nominal=volts,
                    channels={"displacement": x, "velocity": v, "voltage": np.full(t.size, volts),
                              "force": np.zeros(t.size)})
    return test, rest


def test_a_still_stretch_is_at_rest_and_a_sines_reversal_is_not():
    test, truth = held_sine()
    found = at_rest_mask(test.channels["velocity"], test.time)
    np.testing.assert_array_equal(found, truth)
    # no hold: the reversals pass v = 0 in a few milliseconds, never REST_MIN_S
    moving, _ = held_sine(rest_s=0.0)
    assert not at_rest_mask(moving.channels["velocity"], moving.time).any()
    # a hold shorter than REST_MIN_S is not rest either; one just longer is
    short, _ = held_sine(rest_s=0.8 * REST_MIN_S)
    assert not at_rest_mask(short.channels["velocity"], short.time).any()
    longer, truth = held_sine(rest_s=1.2 * REST_MIN_S)
    np.testing.assert_array_equal(at_rest_mask(longer.channels["velocity"], longer.time), truth)
    # a test that never moves (sensor noise only) is at rest throughout
    rng = np.random.default_rng(0)
    assert at_rest_mask(1e-4 * rng.standard_normal(500), np.arange(500) * DT).all()


def test_the_errors_placed_at_rest_are_the_ones_reported():
    """Measured force = the model's own force, 12 N lower at rest: bias +12 N and RMSE 12 N there,
    0 elsewhere; the force's own change at rest within a test is the measured force's there, by hand
    (the derived acceleration settles over the first milliseconds of a hold, so it is not 0)."""
    model = default_model()
    tests, preds, devs = [], [], []
    for volts in (1.0, 4.0):
        test, rest = held_sine(volts=volts)
        pred = predict_force(model, test)
        test.channels["force"] = pred - 12.0 * rest
        tests.append(test), preds.append(pred)
        devs.append(test.channels["force"][rest] - np.mean(test.channels["force"][rest]))
    reg = region_errors(model, tests, preds)
    r = reg["at_rest"]
    assert r["bias_n"] == pytest.approx(12.0, abs=1e-9) and r["rmse_n"] == pytest.approx(12.0, abs=1e-9)
    assert r["rmse_elsewhere_n"] == pytest.approx(0.0, abs=1e-9)
    assert r["force_rms_n"] == pytest.approx(float(np.sqrt(np.mean(np.concatenate(devs) ** 2))), rel=1e-12)
    assert r["share_time"] == pytest.approx(1.0 / 3.0, abs=2e-3) and r["controls"] == [1.0, 4.0]
    assert [p["rmse_at_rest_n"] for p in reg["per_test"]] == pytest.approx([12.0, 12.0], abs=1e-9)
    line = summary_lines(reg)[0]
    assert line.startswith("at rest (") and "RMSE 12.0 N (bias +12.0 N" in line and "against 0.0 N elsewhere" in line


def test_no_still_stretch_no_claim_at_rest():
    model = default_model()
    test, _ = held_sine(rest_s=0.0)
    pred = predict_force(model, test)
    test.channels["force"] = pred + 5.0
    reg = region_errors(model, [test], [pred])
    assert reg["at_rest"] is None and "not measured here (no sample stands still" in reg["note"]
    lines = summary_lines(reg)
    assert lines[0] == reg["note"] and not any("RMSE" in ln and "at rest" in ln for ln in lines)


def test_outside_the_envelope_is_coverages_outside_step_by_step():
    """outside_steps marks the steps coverage() counts (ranges only, and with a joint envelope), and
    the error there is the error on those steps."""
    model = default_model()
    rng = np.random.default_rng(1)
    lo, hi = np.asarray(model.sat_lo), np.asarray(model.sat_hi)
    X = lo + (hi - lo) * rng.uniform(-0.3, 1.3, size=(4000, model.n_inputs))
    X[:5, 0] = np.nan                                   # non-finite inputs are outside
    for env in (None, build_envelope(model, lo + (hi - lo) * rng.uniform(0, 1, size=(3000, model.n_inputs)))):
        out = outside_steps(model, X, env)
        cov = coverage(model, X, env, dt=DT)
        assert 0.05 < out.mean() < 0.95 and out[:5].all()
        assert out.mean() == pytest.approx(cov["outside"]["share_steps"], abs=1e-12)
        t = np.cumsum(rng.uniform(0.5, 1.5, len(X))) * DT    # unequal steps: time and steps differ
        for kw in (dict(dt=DT), dict(t=t)):   # the full car's per-corner shares, exactly coverage's
            assert outside_shares(model, X, env, **kw) == {k: coverage(model, X, env, **kw)["outside"][k]
                                                           for k in ("share_steps", "share_time")}
        if env is not None:   # the bounded search (Envelope.far) is the nearest distance's test, row by row
            np.testing.assert_array_equal(env.far(X), ~(env.nearest(X)[0] <= env.threshold))
    test, _ = held_sine(rest_s=0.0, amp=0.2)          # ten times the stroke: beyond the training ranges
    pred = predict_force(model, test)
    test.channels["force"] = pred + np.where(np.abs(test.channels["velocity"]) > hi[0], 30.0, 0.0)
    o = region_errors(model, [test], [pred])["outside_envelope"]
    assert 0 < o["share_time"] < 1 and o["rmse_n"] == pytest.approx(30.0, abs=1e-9)
    assert o["rmse_inside_n"] == pytest.approx(0.0, abs=1e-9) and o["measure"] == "ranges"


def test_a_real_records_still_ends_are_at_rest():
    """A Labcontrol shaking-table record (../shared/data): the table stands still at its start and
    end; those stretches, and no sample of the moving middle, are at rest."""
    from dampnet.data.real import LABCONTROL, load_labcontrol, shared_data_dir

    if not (shared_data_dir() / LABCONTROL).is_dir():
        pytest.skip(f"the real data sets are kept outside the project ({shared_data_dir()}); not on this machine")
    test = next(t for t in load_labcontrol().tests if t.test_id == "ensaio1.1")
    v, t = test.channels["velocity"], test.time
    rest = at_rest_mask(v, t)
    moving = np.flatnonzero(np.abs(v) > 0.2 * np.max(np.abs(v)))
    assert rest.any() and not rest[moving[0]:moving[-1]].any()
    assert rest[:moving[0]].mean() > 0.3 or rest[moving[-1]:].mean() > 0.3


def test_the_diagnosis_localises_the_error_at_rest_only_where_the_data_stand_still():
    """The diagnosis's "where" (dampnet.diagnosis.localise) uses the same at-rest samples: a region
    "at_rest" with the error placed there (its ratio above 1) on held sines, and no such region on
    sines that never stop."""
    from dampnet.data import Dataset
    from dampnet.diagnosis.context import build_context
    from dampnet.diagnosis.localise import localise

    model = default_model()
    for rest_s in (0.5, 0.0):
        tests = []
        for volts in (1.0, 4.0):
            test, rest = held_sine(rest_s=rest_s, volts=volts)
            test.channels["force"] = predict_force(model, test) - 12.0 * rest + 0.5 * np.sin(np.arange(len(rest)))
            tests.append(test)
        regions = localise(build_context(model, Dataset(tests=tests, source="held sines")))["regions"]
        if rest_s:
            assert regions["at_rest"]["ratio"] > 1.5, regions["at_rest"]
        else:
            assert "at_rest" not in regions
