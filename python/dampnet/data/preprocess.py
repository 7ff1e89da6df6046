"""Preprocessing: the derived acceleration, decimation, hold-out splits.

Acceleration, when a test has no acceleration channel: by default the derivative of the velocity
(or the second derivative of the displacement) by dampnet.data.derivative: a zero-phase low-pass at
8x the test's own frequency content (1 to 40 Hz) and central differences, within 0.5 % of the peak
up to 20 Hz, every sample kept (a Savitzky-Golay derivative within 100 ms of the ends, longer below
40 Hz). Measured on virtual-rig data, whose true acceleration is known (`generate(...,
truth_channels=True)`, default sensors: velocity noise 1 mm/s), pooled NRMSE = RMS(a_est -
a_true) / RMS(a_true) over all tests:

                      each test's cut-off (default)   fixed 40 Hz   20 ms moving average (the thesis's)
  quick plan (seed 3)        0.0076                     0.018              0.042
  thesis plan (seed 3)       0.0048                     0.012              0.023

(ACCEL_NRMSE_DOC bounds the default on the quick plan; tests/python/test_data_preprocess.py.)

The thesis's method, a centred moving average of the velocity's gradient over `window`, is kept
for a model that asks for it (the training option acceleration_window [s]; the embedded default
model was trained with 20 ms): it flattens what the loop feeds a model (the true acceleration)
by 4.6 % at 8 Hz and 27 % at 20 Hz, and lets through the noise in its side lobes. Within half a
window of either end its window is shifted inward rather than shrunk.
"""

from __future__ import annotations

import numpy as np

from dampnet.data.derivative import acceleration_method, acceleration_of_motion
from dampnet.data.types import Dataset, DataError, DynoTest

#: the thesis's moving-average window [s] (a model trained with acceleration_window=0.02, such as
#: the embedded default model, is fed its acceleration so)
THESIS_WINDOW_S = 0.020
#: Documented bound on the default's pooled acceleration NRMSE (RMS error / RMS true) on quick-plan rig data.
ACCEL_NRMSE_DOC = 0.01


def moving_average(x: np.ndarray, window: int) -> np.ndarray:
    """Moving average of odd length `window`, centred; within half a window of either end the
    full-length window is shifted inward (not shrunk), so the ends are as smooth as the middle."""
    x = np.asarray(x, dtype=np.float64)
    w = int(window)
    if w < 1:
        raise ValueError(f"window: expected at least 1 sample, got {window}")
    if w % 2 == 0:
        w += 1
    n = x.shape[0]
    w = min(w, n)
    c = np.concatenate(([0.0], np.cumsum(x)))
    lo = np.clip(np.arange(n) - w // 2, 0, n - w)
    return (c[lo + w] - c[lo]) / w


def window_samples(test: DynoTest, window: int | float) -> int:
    """A moving-average window in samples (odd): an int is samples; a float is seconds."""
    if isinstance(window, (int, np.integer)):
        w = int(window)
    else:
        w = int(round(float(window) / test.dt))
    w = max(w, 1)
    return w + 1 if w % 2 == 0 else w


def acceleration_key(test: DynoTest, window: int | float | None) -> str:
    """What add_acceleration marks a test's derived acceleration with (to know when to derive it
    again): 'zero_phase', or 'moving_average:N' (N samples)."""
    return "zero_phase" if window is None else f"moving_average:{window_samples(test, window)}"


def derive_acceleration(test: DynoTest, window: int | float | None = None) -> tuple[np.ndarray, float | None]:
    """(acceleration [m/s^2] of one test, from its velocity (or, without one, its displacement); the
    zero-phase derivative's cut-off [Hz], None for a moving average). window None: the zero-phase
    derivative (dampnet.data.derivative, its cut-off from the test's content); else the thesis's
    moving average of the gradient over `window` (int = samples, float = seconds)."""
    t = test.time
    if "velocity" in test.channels:
        y, order = test.channels["velocity"], 1
    elif "displacement" in test.channels:
        y, order = test.channels["displacement"], 2
    else:
        raise DataError(f"test {test.test_id}: no velocity or displacement channel to differentiate")
    if window is None:
        return acceleration_of_motion(y, t, order)
    a = np.gradient(y, t, edge_order=2)
    if order == 2:
        a = np.gradient(a, t, edge_order=2)
    return moving_average(a, window_samples(test, window)), None


def acceleration_of(test: DynoTest, window: int | float | None = None) -> np.ndarray:
    """Acceleration [m/s^2] of one test (derive_acceleration without its cut-off)."""
    return derive_acceleration(test, window)[0]


def acceleration_record(ds_or_test, window: int | float | None) -> dict:
    """How the acceleration is derived, for a dataset's or a model's record: the method, and its
    bandwidths [Hz] (each derived test's cut-off, add_acceleration's) or window [s]."""
    if window is not None:
        return {"method": "gradient + centred moving average (the thesis's)", "window": window}
    tests = ds_or_test.tests if isinstance(ds_or_test, Dataset) else [ds_or_test]
    return acceleration_method(t.meta["acceleration_bandwidth_hz"] for t in tests
                               if "acceleration_bandwidth_hz" in t.meta)


def add_acceleration(ds_or_test, window: int | float | None = None):
    """Fill channels['acceleration'] [m/s^2] of a test or of every test of a dataset (in place);
    a zero-phase derivative's cut-off [Hz] goes to the test's meta['acceleration_bandwidth_hz'].

    `window`: None (the default) = the zero-phase derivative; a moving-average length (int =
    samples, float = seconds) = the thesis's method. Returns its argument.
    """
    tests = ds_or_test.tests if isinstance(ds_or_test, Dataset) else [ds_or_test]
    for t in tests:
        t.channels["acceleration"], fc = derive_acceleration(t, window)
        t.meta["acceleration_derived"] = acceleration_key(t, window)
        t.meta.pop("acceleration_bandwidth_hz", None)
        if fc is not None:
            t.meta["acceleration_bandwidth_hz"] = fc
    if isinstance(ds_or_test, Dataset):
        ds_or_test.meta["acceleration"] = acceleration_record(ds_or_test, window)
    return ds_or_test


def acceleration_error(tests: list[DynoTest], truth: list[np.ndarray], window) -> float:
    """Pooled NRMSE of the derived acceleration: RMS(a_est - a_true) / RMS(a_true)."""
    err2 = ref2 = 0.0
    for t, a in zip(tests, truth):
        e = acceleration_of(t, window) - a
        err2 += float(np.sum(e * e))
        ref2 += float(np.sum(a * a))
    return float(np.sqrt(err2 / ref2))


def choose_window(tests: list[DynoTest], truth: list[np.ndarray],
                  candidates_s=(0.002, 0.005, 0.010, 0.015, 0.020, 0.030, 0.050, 0.100)):
    """(best moving-average window [s], {window [s]: pooled NRMSE}) over candidate windows, on data
    with known truth (the thesis's method; the default's own error: acceleration_error(..., None))."""
    errs = {w: acceleration_error(tests, truth, float(w)) for w in candidates_s}
    return min(errs, key=errs.get), errs


#: training's automatic decimation keeps about this rate [Hz] (training.pipeline's module doc) ...
DECIMATE_TARGET_HZ = 200.0
#: ... or about this one [Hz] when the training rows at DECIMATE_TARGET_HZ would be more than
#: DECIMATE_MAX_ROWS. Why (issue 33, bench/LOG.md "The thesis plan at 100 Hz"): an LM epoch costs
#: rows x weights^2, and a large plan's extra rows at 200 Hz are more samples of the same cycles. On the
#: thesis plan (91,518 rows at 200 Hz, 45,780 at 100 Hz) a training at 100 Hz is half as long and no
#: less accurate on the held-out level.
DECIMATE_LARGE_HZ = 100.0
DECIMATE_MAX_ROWS = 50_000
#: what the automatic decimation does, in words (the training option's and the request field's help)
AUTO_DECIMATE_RULE = f"about {DECIMATE_TARGET_HZ:g} Hz, {DECIMATE_LARGE_HZ:g} Hz beyond {DECIMATE_MAX_ROWS:,} training rows"


def auto_decimate(ds: Dataset) -> int:
    """Training's automatic decimation factor for `ds` (the training tests): its first test's rate over
    DECIMATE_TARGET_HZ (rounded), or over DECIMATE_LARGE_HZ (rounded down: never below that rate) when
    the first would leave more than DECIMATE_MAX_ROWS rows."""
    if not ds.tests:
        return 1
    fs = 1.0 / ds.tests[0].dt
    factor = max(1, int(round(fs / DECIMATE_TARGET_HZ)))
    if decimated_rows(ds, factor) > DECIMATE_MAX_ROWS:
        factor = max(factor, int(fs / DECIMATE_LARGE_HZ + 1e-9))
    return factor


def decimated_rows(ds: Dataset, factor: int) -> int:
    """The samples decimate(ds, factor) keeps, over every test (each test's first, then every factor-th)."""
    return sum(-(-len(t) // int(factor)) for t in ds.tests)


def decimate(ds: Dataset, factor: int) -> Dataset:
    """Keep every `factor`-th sample of every channel (for training speed); a new Dataset.

    No anti-alias filter: dyno signals at 5 kHz are far oversampled for 0.25-3 Hz
    tests, and the noise left is the measurement's. Derive acceleration first.
    """
    factor = int(factor)
    if factor < 1:
        raise ValueError(f"decimate: factor: expected an integer >= 1, got {factor}")
    tests = [t.copy(time=t.time[::factor].copy(),
                    channels={k: v[::factor].copy() for k, v in t.channels.items()})
             for t in ds.tests]
    for t in tests:
        t.meta["decimated_by"] = t.meta.get("decimated_by", 1) * factor
    return ds.subset(tests, note=f"decimate({factor})")


#: what to do when a hold-out request matches no test (the training pipeline's and restarts' DataError)
HOLDOUT_HINT = "choose another --holdout-voltage, name --holdout-tests, or --holdout-voltage none"


def holdout_split(ds: Dataset, voltage: float | None, test_ids=None,
                  atol: float = 1e-6) -> tuple[Dataset, Dataset]:
    """(train, holdout): hold out all tests at nominal `voltage` [V] (None: none; the training's
    default: dampnet.training.settings.OPTIONS) and/or the tests named in `test_ids`. ValueError if nothing would be held out."""
    ids = set(test_ids or ())
    unknown = ids - set(ds.test_ids)
    if unknown:
        raise ValueError(f"holdout_split: unknown test ids {sorted(unknown)}")

    def held(t: DynoTest) -> bool:
        if t.test_id in ids:
            return True
        return (voltage is not None and t.control_nominal is not None
                and abs(t.control_nominal - voltage) <= atol)

    hold = [t for t in ds.tests if held(t)]
    if not hold:
        raise ValueError(f"holdout_split: no test at control {voltage!r} or in test_ids: nothing to hold out")
    train = [t for t in ds.tests if not held(t)]
    return (ds.subset(train, note="holdout_split:train"), ds.subset(hold, note="holdout_split:holdout"))


def split_by_tests(ds: Dataset, fraction: float = 0.2, seed: int = 0) -> tuple[Dataset, Dataset]:
    """(train, test): a random `fraction` of whole tests goes to the second set (at least one)."""
    if not 0 < fraction < 1:
        raise ValueError(f"split_by_tests: fraction: expected 0 < fraction < 1, got {fraction}")
    n = len(ds.tests)
    if n < 2:
        raise ValueError("split_by_tests: need at least two tests")
    k = min(max(1, int(round(fraction * n))), n - 1)
    pick = set(np.random.default_rng(seed).choice(n, size=k, replace=False).tolist())
    a = [t for i, t in enumerate(ds.tests) if i not in pick]
    b = [t for i, t in enumerate(ds.tests) if i in pick]
    return ds.subset(a, note="split_by_tests:train"), ds.subset(b, note="split_by_tests:test")
