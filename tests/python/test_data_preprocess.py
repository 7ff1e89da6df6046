"""Acceleration derivation (error on rig data within the documented figure), decimation, splits."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dampnet.data import DEFAULT_WINDOW_S, add_acceleration, decimate, holdout_split, split_by_tests
from dampnet.data.preprocess import ACCEL_NRMSE_DOC, acceleration_error, choose_window, moving_average
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
    from dampnet.data import DynoTest

    t = np.linspace(0, 1, 501)
    test = DynoTest("p", t, {"displacement": 1.5 * t ** 2, "velocity": 3.0 * t, "force": t, "voltage": 0 * t})
    add_acceleration(test, window=11)
    np.testing.assert_allclose(test.channels["acceleration"], 3.0, rtol=1e-9)
    del test.channels["velocity"]                      # from displacement alone: second differences
    add_acceleration(test, window=11)
    np.testing.assert_allclose(test.channels["acceleration"], 3.0, rtol=1e-6)


def test_acceleration_error_on_rig_data_is_within_the_documented_figure(quick_truth):
    truth = [t.channels["true_acceleration"] for t in quick_truth.tests]
    err = acceleration_error(quick_truth.tests, truth, DEFAULT_WINDOW_S)
    assert err <= ACCEL_NRMSE_DOC
    best, errs = choose_window(quick_truth.tests, truth)
    assert errs[DEFAULT_WINDOW_S] <= 1.1 * errs[best]          # the default is still (near) the best
    assert errs[0.002] > 2 * err and errs[0.100] > 2 * err     # too short: noise; too long: bias
    ds = add_acceleration(quick_truth.subset([t.copy() for t in quick_truth.tests]))
    assert ds.tests[0].meta["acceleration_window_samples"] == 101


def test_acceleration_error_on_the_thesis_plan_is_the_documented_figure():
    """docs/data-formats.md: '2.3 % RMS error on the thesis plan' (measured 0.0234 with seed 3; the whole
    plan, 180 tests x 10000 samples, is generated in about a second)."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "data-formats.md").read_text()
    assert "2.3 % RMS error on the thesis plan" in " ".join(doc.split())
    ds = generate("thesis", seed=3, truth_channels=True)
    err = acceleration_error(ds.tests, [t.channels["true_acceleration"] for t in ds.tests], DEFAULT_WINDOW_S)
    assert 0.023 / 1.5 < err < 0.023 * 1.3, err


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
    from dampnet.data.preprocess import acceleration_of
    from dampnet.training.pipeline import prepare_training

    ds = quick_truth.subset([t.copy() for t in quick_truth.tests])
    for t in ds.tests:
        t.channels.pop("acceleration", None)
        t.meta.pop("acceleration_window_samples", None)
    prepare_training(ds, decimate=50)
    t = ds.tests[0]
    assert t.meta["acceleration_window_samples"] == 101  # 20 ms at 5 kHz
    prepare_training(ds, decimate=50, acceleration_window=0.010)
    assert t.meta["acceleration_window_samples"] == 51
    np.testing.assert_array_equal(t.channels["acceleration"], acceleration_of(t, 0.010))
    # a measured channel (no derivation mark) is the user's and is kept
    measured = ds.tests[1]
    measured.meta.pop("acceleration_window_samples")
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
