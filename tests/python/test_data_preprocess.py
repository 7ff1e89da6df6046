"""Acceleration derivation (against analytic sines and on rig data within the documented figures),
decimation, splits. Cost: about 6 s (two rig datasets generated, the thesis plan's in about 2 s)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dampnet.data import derivative
from dampnet.data import THESIS_WINDOW_S, DynoTest, add_acceleration, decimate, holdout_split, split_by_tests
from dampnet.data.preprocess import ACCEL_NRMSE_DOC, acceleration_error, acceleration_of, choose_window, moving_average
from dampnet.rig import generate


@pytest.fixture(scope="module")
def quick_truth():
    return generate("quick", seed=21, truth_channels=True)


def test_moving_average_against_a_direct_sum():
    x = np.random.default_rng(0).normal(size=200)
    y = moving_average(x, 7)
    for k in (3, 50, 196):
        lo = min(max(k - 3, 0), 200 - 7)
        assert y[k] == pytest.approx(np.mean(x[lo:lo + 7]), rel=1e-12)


def test_acceleration_of_a_parabola_is_exact():
    t = np.linspace(0, 1, 501)
    test = DynoTest("p", t, {"displacement": 1.5 * t ** 2, "velocity": 3.0 * t, "force": t, "voltage": 0 * t})
    for window, rtol in ((None, 1e-8), (11, 1e-9)):        # the zero-phase derivative; the thesis's average
        np.testing.assert_allclose(acceleration_of(test, window), 3.0, rtol=rtol)
    del test.channels["velocity"]                      # from displacement alone: second derivatives
    for window, rtol in ((None, 1e-5), (11, 1e-6)):    # (the low-pass's start-up on the curved ends: 3e-6)
        np.testing.assert_allclose(acceleration_of(test, window), 3.0, rtol=rtol)


def _sine_errors(fs: float, f: float, window, channel: str) -> tuple[float, float]:
    """(worst error over the whole test, worst beyond 100 ms of the ends) of the derived acceleration
    of sines at f [Hz] sampled at fs [Hz] (2.3 cycles, at least 2.3 s; 8 phases), as a fraction of
    the analytic acceleration's peak."""
    dt = 1.0 / fs
    t = np.arange(int(max(2.3 / f, 2.3) * fs)) * dt
    w0 = 2 * np.pi * f
    worst = inner = 0.0
    for phase in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        x, v, a = np.sin(w0 * t + phase) / w0, np.cos(w0 * t + phase), -w0 * np.sin(w0 * t + phase)
        test = DynoTest("s", t, {channel: x if channel == "displacement" else v, "force": t, "voltage": 0 * t})
        e = np.abs(acceleration_of(test, window) - a) / w0
        n = int(round(0.1 * fs))
        worst, inner = max(worst, float(e.max())), max(inner, float(e[n:-n].max()))
    return worst, inner


@pytest.mark.parametrize("fs", [1000.0, 5000.0])
def test_acceleration_of_sines_is_within_half_a_percent_of_the_peak_up_to_20_hz(fs):
    """Issue 49, item 17: the default derivative (dampnet.data.derivative) against the analytic
    acceleration of 1, 8 and 20 Hz sines at 1 and 5 kHz: within 0.5 % of the peak, ends included,
    from a velocity; from a displacement alone within 0.5 % beyond 100 ms of the ends, 2.5 % at the
    outermost samples. The thesis's 20 ms moving average, its default before, is 4.6 % low at 8 Hz
    and 27 % at 20 Hz (measured 0.99 and 26 % here), and 6 % off at the ends even at 1 Hz."""
    for f in (0.2, 1.0, 8.0, 20.0):
        worst, _ = _sine_errors(fs, f, None, "velocity")
        assert worst <= 0.005, (f, worst)
        worst, inner = _sine_errors(fs, f, None, "displacement")
        assert inner <= 0.005 and worst <= 0.03, (f, worst, inner)
    assert _sine_errors(fs, 8.0, THESIS_WINDOW_S, "velocity")[1] > 0.04
    assert _sine_errors(fs, 20.0, THESIS_WINDOW_S, "velocity")[1] > 0.2


def test_acceleration_error_on_rig_data_is_within_the_documented_figure(quick_truth):
    truth = [t.channels["true_acceleration"] for t in quick_truth.tests]
    err = acceleration_error(quick_truth.tests, truth, None)
    assert err <= ACCEL_NRMSE_DOC
    # the thesis's moving average: its best window is 2.3x the default's error, 20 ms 2.3x too
    best, errs = choose_window(quick_truth.tests, truth)
    assert errs[best] > 2 * err and errs[THESIS_WINDOW_S] > 2 * err, (err, errs)
    ds = add_acceleration(quick_truth.subset([t.copy() for t in quick_truth.tests]))
    assert ds.tests[0].meta["acceleration_derived"] == "zero_phase"
    cuts = [t.meta["acceleration_bandwidth_hz"] for t in ds.tests]
    assert ds.meta["acceleration"]["bandwidth_hz"] == sorted({round(c, 1) for c in cuts})
    assert "zero-phase" in ds.meta["acceleration"]["method"] and "velocity power" in ds.meta["acceleration"]["method"]
    # each test's own cut-off (8x its content, here 3 to 36 Hz) against the fixed 40 Hz ceiling:
    # less noise on the slow tests, in the middle and at the ends (measured 0.0091 against 0.0182,
    # seed 21)
    assert 2.0 < min(cuts) < max(cuts) < 40.0
    fixed = _with_fixed_cutoff(lambda: acceleration_error(quick_truth.tests, truth, None))
    assert err < 0.6 * fixed, (err, fixed)


def _with_fixed_cutoff(fn):
    """fn() with the acceleration's cut-off fixed at ACCELERATION_CUTOFF_HZ (the default before issue
    53's per-test cut-off)."""
    factor = derivative.CONTENT_FACTOR
    derivative.CONTENT_FACTOR = None
    try:
        return fn()
    finally:
        derivative.CONTENT_FACTOR = factor


def test_content_frequency_against_scipy_periodogram():
    """The frequency below which 90 % of the power lies: a sine's own frequency (to the spectrum's
    resolution, 1/T), band-limited noise's upper band within 10 % of scipy.signal.welch's figure;
    nothing for a constant. Cost: < 0.1 s."""
    import scipy.signal

    dt, t = 1e-3, np.arange(20000) * 1e-3
    for f in (0.3, 2.0, 17.0):
        assert abs(derivative.content_frequency(np.sin(2 * np.pi * f * t + 0.4), dt) - f) <= 1.0 / t[-1]
    noise = np.random.default_rng(1).normal(size=t.size)
    band = scipy.signal.sosfiltfilt(scipy.signal.butter(8, 12.0, fs=1 / dt, output="sos"), noise)
    fw, p = scipy.signal.welch(band, fs=1 / dt, nperseg=4096)
    f90 = fw[np.searchsorted(np.cumsum(p), 0.9 * np.sum(p))]
    assert abs(derivative.content_frequency(band, dt) - f90) <= 0.1 * f90, f90
    assert derivative.content_frequency(np.full(100, 3.0), dt) == 0.0


def test_acceleration_cutoff_follows_the_test_within_its_bounds():
    """8x a sine's frequency; the ceiling (40 Hz, or a quarter of the rate) for broadband or fast
    motion; the floor (1 Hz) for a very slow test or none at all. Cost: < 0.1 s."""
    dt, t = 1e-3, np.arange(20000) * 1e-3
    assert derivative.acceleration_cutoff(np.sin(2 * np.pi * 1.5 * t), dt) == pytest.approx(12.0, abs=8 / t[-1])
    assert derivative.acceleration_cutoff(np.sin(2 * np.pi * 15.0 * t), dt) == 40.0
    assert derivative.acceleration_cutoff(np.sin(2 * np.pi * 15.0 * t[::10]), 10 * dt) == 25.0   # 100 Hz
    assert derivative.acceleration_cutoff(np.random.default_rng(2).normal(size=t.size), dt) == 40.0
    assert derivative.acceleration_cutoff(np.sin(2 * np.pi * 0.05 * t), dt) == 1.0
    assert derivative.acceleration_cutoff(np.zeros(50), dt) == 1.0
    assert _with_fixed_cutoff(lambda: derivative.acceleration_cutoff(np.sin(2 * np.pi * 1.5 * t), dt)) == 40.0


def test_acceleration_error_on_the_quick_plan_is_the_documented_table():
    """dampnet.data.preprocess's table, quick plan, seed 3: 0.0076 with each test's cut-off, 0.018 at a
    fixed 40 Hz (and docs/data-formats.md's '0.8 % RMS error on the quick plan'). Cost: 1 s."""
    doc = " ".join((Path(__file__).resolve().parents[2] / "docs" / "data-formats.md").read_text().split())
    assert "0.8 % RMS error on the quick plan" in doc
    ds = generate("quick", seed=3, truth_channels=True)
    truth = [t.channels["true_acceleration"] for t in ds.tests]
    err = acceleration_error(ds.tests, truth, None)
    fixed = _with_fixed_cutoff(lambda: acceleration_error(ds.tests, truth, None))
    assert 0.0076 / 1.3 < err < 0.0076 * 1.3 and 0.018 / 1.3 < fixed < 0.018 * 1.3, (err, fixed)


def test_acceleration_error_on_the_thesis_plan_is_the_documented_figure():
    """docs/data-formats.md: '0.5 % RMS error on the thesis plan' (measured 0.0048 with seed 3, 0.0119
    at a fixed 40 Hz, 0.0234 with the thesis's 20 ms moving average; the whole plan, 180 tests x 10000
    samples, is generated in about 2 s)."""
    doc = " ".join((Path(__file__).resolve().parents[2] / "docs" / "data-formats.md").read_text().split())
    assert "0.5 % RMS error on the thesis plan" in doc and "(4.2 % and 2.3 %;" in doc
    ds = generate("thesis", seed=3, truth_channels=True)
    truth = [t.channels["true_acceleration"] for t in ds.tests]
    err = acceleration_error(ds.tests, truth, None)
    assert 0.005 / 1.3 < err < 0.005 * 1.3, err
    thesis = acceleration_error(ds.tests, truth, THESIS_WINDOW_S)
    assert 0.023 / 1.3 < thesis < 0.023 * 1.3, thesis


def test_a_trained_model_and_train_say_how_the_acceleration_was_derived(quick_truth, tmp_path, capsys):
    """Issue 49, item 17: the method and its bandwidth in the model's record and in `dampnet train`'s
    output; the thesis's window when asked for; nothing when the data carry their own acceleration.
    Cost: about 6 s (four trainings of 2 epochs on every 50th sample, one through the CLI)."""
    from dampnet.cli import main
    from dampnet.data import write_dataset
    from dampnet.training.pipeline import train_dataset

    def fresh():
        ds = quick_truth.subset([t.copy() for t in quick_truth.tests])
        for t in ds.tests:
            t.channels.pop("acceleration", None)
            t.meta.pop("acceleration_derived", None)
        return ds

    m, _, _ = train_dataset(fresh(), decimate=50, max_epochs=2)
    rec = m.meta["data"]["acceleration"]
    assert 2.0 < min(rec["bandwidth_hz"]) < max(rec["bandwidth_hz"]) <= 40.0 and rec["method"].startswith("zero-phase Butterworth low-pass of the velocity")
    m, _, _ = train_dataset(fresh(), decimate=50, max_epochs=2, acceleration_window=0.02)
    assert m.meta["data"]["acceleration"] == {"method": "gradient + centred moving average (the thesis's)", "window": 0.02}
    measured = fresh()
    for t in measured.tests:
        t.channels["acceleration"] = t.channels["true_acceleration"]
    m, _, _ = train_dataset(measured, decimate=50, max_epochs=2)
    assert "acceleration" not in m.meta["data"]
    ds = fresh()
    for t in ds.tests:
        for c in ("true_force", "true_acceleration"):
            t.channels.pop(c, None)
    write_dataset(ds, tmp_path / "data")
    assert main(["train", str(tmp_path / "data"), "--out", str(tmp_path / "m"), "--max-epochs", "2",
                 "--decimate", "50", "--restarts", "1", "--valve", "off"]) == 0
    out = capsys.readouterr().out
    assert "acceleration derived: zero-phase Butterworth low-pass of the velocity" in out
    lo, hi = min(rec["bandwidth_hz"]), max(rec["bandwidth_hz"])
    assert f"bandwidth {lo:.3g} to {hi:.3g} Hz" in out, out


def test_decimate_keeps_every_nth_sample(quick_truth):
    d = decimate(quick_truth, 10)
    for a, b in zip(quick_truth.tests, d.tests):
        assert len(b) == (len(a) + 9) // 10
        np.testing.assert_array_equal(b.channels["force"], a.channels["force"][::10])
        np.testing.assert_array_equal(b.time, a.time[::10])
    assert len(quick_truth.tests[0]) > len(d.tests[0])       # the original is untouched
    with pytest.raises(ValueError):
        decimate(quick_truth, 0)


def test_holdout_split_is_the_thesis_split(quick_truth):
    train, hold = holdout_split(quick_truth, 2.25)
    assert {t.control_nominal for t in hold.tests} == {2.25}
    assert 2.25 not in {t.control_nominal for t in train.tests}
    assert len(train) + len(hold) == len(quick_truth)
    assert hold.meta["seed"] == 21
    train2, hold2 = holdout_split(quick_truth, voltage=None, test_ids=["T001", "T009"])
    assert hold2.test_ids == ["T001", "T009"] and len(train2) == len(quick_truth) - 2
    with pytest.raises(ValueError, match="nothing to hold out"):
        holdout_split(quick_truth, voltage=1.7)
    with pytest.raises(ValueError, match="unknown test ids"):
        holdout_split(quick_truth, 2.25, test_ids=["nope"])


def test_split_by_tests_is_disjoint_and_seeded(quick_truth):
    a, b = split_by_tests(quick_truth, 0.3, seed=1)
    assert set(a.test_ids).isdisjoint(b.test_ids) and len(a) + len(b) == len(quick_truth)
    assert split_by_tests(quick_truth, 0.3, seed=1)[1].test_ids == b.test_ids


def test_training_rederives_acceleration_for_another_window(quick_truth):
    """Training derives the acceleration in place; a later training of the same dataset with another
    window must use that window's acceleration, not the first one's (it once silently did not)."""
    from dampnet.training.pipeline import prepare_training

    ds = quick_truth.subset([t.copy() for t in quick_truth.tests])
    for t in ds.tests:
        t.channels.pop("acceleration", None)
        t.meta.pop("acceleration_derived", None)
    prepare_training(ds, decimate=50)
    t = ds.tests[0]
    assert t.meta["acceleration_derived"] == "zero_phase"
    np.testing.assert_array_equal(t.channels["acceleration"], acceleration_of(t))
    prepare_training(ds, decimate=50, acceleration_window=0.010)
    assert t.meta["acceleration_derived"] == "moving_average:51"      # 10 ms at 5 kHz
    np.testing.assert_array_equal(t.channels["acceleration"], acceleration_of(t, 0.010))
    prepare_training(ds, decimate=50)
    np.testing.assert_array_equal(t.channels["acceleration"], acceleration_of(t))
    # a measured channel (no derivation mark) is the user's and is kept
    measured = ds.tests[1]
    measured.meta.pop("acceleration_derived")
    kept = measured.channels["acceleration"].copy()
    prepare_training(ds, decimate=50, acceleration_window=0.040)
    np.testing.assert_array_equal(measured.channels["acceleration"], kept)


def test_auto_decimation_is_200_hz_and_100_hz_for_large_training_sets():
    """About DECIMATE_TARGET_HZ (200 Hz: 25 at 5 kHz), and about DECIMATE_LARGE_HZ (100 Hz: 50) once
    200 Hz would leave more than DECIMATE_MAX_ROWS rows, counted over every test as decimate() keeps
    them (rounded up per test); 1 kHz data: 5, then 10. The large data's rate is never below 100 Hz."""
    from dampnet.data import Dataset, DynoTest
    from dampnet.data.preprocess import DECIMATE_LARGE_HZ, DECIMATE_MAX_ROWS, DECIMATE_TARGET_HZ, auto_decimate

    def dataset(rate_hz, n_tests, samples):
        t = np.arange(samples) / rate_hz
        z = np.zeros(samples)
        return Dataset([DynoTest(f"t{i}", t, {"displacement": z, "velocity": z, "force": z, "voltage": z})
                        for i in range(n_tests)], "hand-made")

    assert (DECIMATE_TARGET_HZ, DECIMATE_LARGE_HZ) == (200.0, 100.0)
    rows_per_test = 1_000
    at_cap = DECIMATE_MAX_ROWS // rows_per_test
    for rate, small, large in ((5000.0, 25, 50), (1000.0, 5, 10)):
        samples = rows_per_test * small  # rows_per_test rows each at 200 Hz
        assert auto_decimate(dataset(rate, at_cap, samples)) == small          # exactly the cap: 200 Hz
        assert auto_decimate(dataset(rate, at_cap, samples + 1)) == large      # one more row per test
        assert auto_decimate(dataset(rate, at_cap + 1, samples)) == large
        assert auto_decimate(dataset(rate, 3, samples)) == small
    assert auto_decimate(dataset(150.0, 400, 2_000)) == 1  # 75 Hz would be below 100 Hz
    assert auto_decimate(dataset(250.0, 400, 2_000)) == 2  # 125 Hz
    assert auto_decimate(dataset(250.0, 4, 2_000)) == 1
    assert auto_decimate(Dataset([], "empty")) == 1
