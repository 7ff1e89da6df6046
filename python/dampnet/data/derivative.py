"""Time derivatives of measured channels: velocity from displacement, acceleration from velocity.

One home for both (issue 49, item 17): a zero-phase Butterworth low-pass (order ORDER,
scipy.signal.sosfiltfilt, so no delay) followed by 4th-order central differences. Its gain is
1 / (1 + (f / f_c)^8) (the filter runs forwards and backwards), so a cut-off f_c keeps the bias
below 0.5 % of the peak up to f_c / 1.94: 0.4 % at 20 Hz for the acceleration's 40 Hz, 0.07 % for
the velocity's 50 Hz. The thesis's 20 ms moving average, which this replaces as the default, is
sinc-shaped: 4.6 % low at 8 Hz, 27 % at 20 Hz, and its side lobes pass the high-frequency noise
that a derivative amplifies (on the virtual rig, whose true acceleration is known, pooled NRMSE
1.8 % against 4.2 % on the quick plan, 1.2 % against 2.3 % on the thesis plan).

The ends: a filter run forwards and backwards needs samples beyond the ends and invents them
(odd reflection), which errs by up to 37 % of the peak of a 20 Hz sine in the first and last
20 ms, and still 0.3 % 50 ms in. A velocity derived by a reader has EDGE_S cut from each end
(dampnet.data.testbuild). An acceleration keeps every sample, so that it stays aligned with the
other channels: within ACCEL_EDGE_S of each end it is a Savitzky-Golay derivative instead
(scipy.signal.savgol_filter, degree EDGE_POLYORDER over EDGE_WINDOW_S, the last window's fit at
the ends): unbiased, noisier than the interior (a wider band). Against the analytic derivative of
1, 8 and 20 Hz sines at 1 and 5 kHz (tests/python/test_data_preprocess.py) the acceleration of a
velocity is within 0.42 % of the peak, ends included; of a displacement alone (a derivative of a
derivative) within 0.43 % beyond ACCEL_EDGE_S, and up to 2.5 % at the outermost samples at 20 Hz.
"""

from __future__ import annotations

import numpy as np

#: the low-pass's order (sosfiltfilt doubles it)
ORDER = 4
#: the velocity's cut-off [Hz] (derived from displacement; at most a quarter of the sample rate)
VELOCITY_CUTOFF_HZ = 50.0
#: the acceleration's cut-off [Hz] (derived from velocity): about the lowest that keeps 20 Hz within
#: 0.5 % (the lower, the less noise: pooled rig NRMSE 1.2 % at 30 Hz, 1.3 % at 40, 1.6 % at 50)
ACCELERATION_CUTOFF_HZ = 40.0
#: the span at each end where the low-pass errs [s]: cut from a velocity derived by a reader
EDGE_S = 0.05
#: the span at each end where an acceleration is the Savitzky-Golay derivative [s] (the low-pass's
#: start-up still errs by 0.3 % of the peak 50 ms in)
ACCEL_EDGE_S = 0.1
#: the Savitzky-Golay derivative within ACCEL_EDGE_S of the ends: its window [s] and polynomial degree
EDGE_WINDOW_S = 0.018
EDGE_POLYORDER = 5


def sample_interval(t: np.ndarray) -> float:
    """The sample interval [s] of times t [s] (their median step)."""
    return float(np.median(np.diff(t)))


def cutoff(dt: float, wanted_hz: float) -> float:
    """The cut-off [Hz] used at sample interval dt [s]: wanted_hz, at most a quarter of the rate."""
    return min(wanted_hz, 0.25 / dt)


def low_pass_derivative(y: np.ndarray, dt: float, cutoff_hz: float) -> np.ndarray:
    """d y / d t of samples y at interval dt [s]: y low-passed at cutoff_hz [Hz], zero-phase, then
    4th-order central differences (2nd order at the two outermost samples)."""
    import scipy.signal  # here: `dampnet --help` imports the data package

    y = np.asarray(y, dtype=np.float64)
    sos = scipy.signal.butter(ORDER, cutoff_hz, fs=1.0 / dt, output="sos")
    z = scipy.signal.sosfiltfilt(sos, y, padtype="odd", padlen=min(y.size - 1, int(round(4 * EDGE_S / dt))))
    d = np.gradient(z, dt, edge_order=2)
    d[2:-2] = (z[:-4] - 8.0 * z[1:-3] + 8.0 * z[3:-1] - z[4:]) / (12.0 * dt)
    return d


def velocity_from_displacement(x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, int, dict]:
    """(velocity [m/s] of displacement x [m] at times t [s], samples to cut at each end, the method
    in words for the dataset's summary)."""
    dt = sample_interval(t)
    fc = cutoff(dt, VELOCITY_CUTOFF_HZ)
    v = low_pass_derivative(x, dt, fc)
    cut = int(round(EDGE_S / dt))
    info = {"method": f"zero-phase Butterworth low-pass of the displacement (order {ORDER}, "
                      "scipy.signal.sosfiltfilt), 4th-order central differences",
            "bandwidth_hz": fc, "edge_cut_s": round(cut * dt, 9)}
    return v, cut, info


def smooth_derivative(y: np.ndarray, t: np.ndarray, cutoff_hz: float) -> np.ndarray:
    """d y / d t at times t [s], every sample kept: low_pass_derivative, and within ACCEL_EDGE_S of
    each end a Savitzky-Golay derivative (see the module doc)."""
    import scipy.signal

    y = np.asarray(y, dtype=np.float64)
    dt = sample_interval(t)
    d = low_pass_derivative(y, dt, cutoff(dt, cutoff_hz))
    n = min(int(round(ACCEL_EDGE_S / dt)), y.size // 2)
    window = int(round(EDGE_WINDOW_S / dt)) | 1          # odd, centred
    if n and window > EDGE_POLYORDER + 1 and y.size >= window:
        edge = scipy.signal.savgol_filter(y, window, EDGE_POLYORDER, deriv=1, delta=dt, mode="interp")
        d[:n], d[-n:] = edge[:n], edge[-n:]
    return d


def acceleration_of_motion(y: np.ndarray, t: np.ndarray, order: int = 1) -> np.ndarray:
    """Acceleration [m/s^2] at times t [s] of velocity y [m/s] (order 1), or of displacement y [m]
    (order 2: the derivative of its velocity), every sample kept."""
    if order == 2:
        y = smooth_derivative(y, t, VELOCITY_CUTOFF_HZ)
    return smooth_derivative(y, t, ACCELERATION_CUTOFF_HZ)


def acceleration_method(dt: float) -> dict:
    """The acceleration's method in words and its bandwidth [Hz] at sample interval dt [s]: for a
    dataset's and a model's record."""
    return {"method": f"zero-phase Butterworth low-pass of the velocity (order {ORDER}, scipy.signal.sosfiltfilt), "
                      f"4th-order central differences; Savitzky-Golay (degree {EDGE_POLYORDER}, "
                      f"{1000 * EDGE_WINDOW_S:g} ms) within {1000 * ACCEL_EDGE_S:g} ms of each end",
            "bandwidth_hz": cutoff(dt, ACCELERATION_CUTOFF_HZ)}
