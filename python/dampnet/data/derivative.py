"""Time derivatives of measured channels: velocity from displacement, acceleration from velocity.

One home for both (issue 49, item 17): a zero-phase Butterworth low-pass (order ORDER,
scipy.signal.sosfiltfilt, so no delay) followed by 4th-order central differences. Its gain is
1 / (1 + (f / f_c)^8) (the filter runs forwards and backwards), so a cut-off f_c keeps the bias
below 0.5 % of the peak up to f_c / 1.94: 0.4 % at 20 Hz for the acceleration's 40 Hz, 0.07 % for
the velocity's 50 Hz. The thesis's 20 ms moving average, which this replaces as the default, is
sinc-shaped: 4.6 % low at 8 Hz, 27 % at 20 Hz, and its side lobes pass the high-frequency noise
that a derivative amplifies (on the virtual rig, whose true acceleration is known, pooled NRMSE
1.8 % against 4.2 % on the quick plan, 1.2 % against 2.3 % on the thesis plan, at 40 Hz).

The acceleration's cut-off is each test's own (issue 53): CONTENT_FACTOR times the frequency below
which CONTENT_SHARE of its velocity's power lies, between MIN_CUTOFF_HZ and ACCELERATION_CUTOFF_HZ.
A fixed 40 Hz left a slow test's acceleration with all the noise up to 40 Hz: on the rig the
per-test cut-off halves the pooled NRMSE (quick plan 0.76 %, thesis plan 0.48 %, seed 3), and on
the real data sets, sampled at 100 Hz to 1 kHz with sines of 0.1 to 5 Hz, it is what the models
trained on them prefer (bench/experiments/real_acceleration.py).

The ends: a filter run forwards and backwards needs samples beyond the ends and invents them
(odd reflection), which errs by up to 37 % of the peak of a 20 Hz sine in the first and last
20 ms, and still 0.3 % 50 ms in. A velocity derived by a reader has EDGE_S cut from each end
(dampnet.data.testbuild). An acceleration keeps every sample, so that it stays aligned with the
other channels: within ACCEL_EDGE_S of each end it is a Savitzky-Golay derivative instead
(scipy.signal.savgol_filter, degree EDGE_POLYORDER over EDGE_WINDOW_S, the last window's fit at
the ends): unbiased, noisier than the interior (a wider band). A lower cut-off starts up more
slowly, so below EDGE_REFERENCE_HZ both spans (and the low-pass's padding) stretch in proportion:
at 8 Hz the ends are 0.5 s, fitted over 90 ms. Against the analytic derivative of 0.2, 1, 8 and 20 Hz sines at 1 and 5 kHz (tests/python/test_data_preprocess.py) the acceleration of a
velocity is within 0.42 % of the peak, ends included; of a displacement alone (a derivative of a
derivative) within 0.43 % beyond ACCEL_EDGE_S, and up to 2.5 % at the outermost samples at 20 Hz.
"""

from __future__ import annotations

import numpy as np

#: the low-pass's order (sosfiltfilt doubles it)
ORDER = 4
#: the velocity's cut-off [Hz] (derived from displacement; at most a quarter of the sample rate)
VELOCITY_CUTOFF_HZ = 50.0
#: the acceleration's highest cut-off [Hz] (derived from velocity): about the lowest that keeps 20 Hz
#: within 0.5 % (the lower, the less noise: pooled rig NRMSE 1.2 % at 30 Hz, 1.3 % at 40, 1.6 % at 50)
ACCELERATION_CUTOFF_HZ = 40.0
#: a test's own cut-off is CONTENT_FACTOR times the frequency below which CONTENT_SHARE of its
#: velocity's power lies (a sine's own frequency; a broadband record's upper band), between
#: MIN_CUTOFF_HZ and ACCELERATION_CUTOFF_HZ: a slow test's acceleration is not left with 40 Hz of
#: noise. 8x keeps the 4th harmonic within 0.4 % (gain 1 / (1 + (f / f_c)^8)). Set CONTENT_FACTOR to
#: None for the fixed ACCELERATION_CUTOFF_HZ (bench/experiments/real_acceleration.py compares both).
CONTENT_SHARE = 0.9
CONTENT_FACTOR: float | None = 8.0
MIN_CUTOFF_HZ = 1.0
#: the span at each end where the low-pass errs [s]: cut from a velocity derived by a reader
EDGE_S = 0.05
#: the span at each end where an acceleration is the Savitzky-Golay derivative [s] (the low-pass's
#: start-up still errs by 0.3 % of the peak 50 ms in)
ACCEL_EDGE_S = 0.1
#: the Savitzky-Golay derivative within ACCEL_EDGE_S of the ends: its window [s] and polynomial degree
EDGE_WINDOW_S = 0.018
EDGE_POLYORDER = 5
#: the cut-off [Hz] the edge spans above are for: at a lower cut-off f_c the low-pass's start-up
#: lasts longer, so the spans (and the low-pass's padding) stretch by EDGE_REFERENCE_HZ / f_c
EDGE_REFERENCE_HZ = 40.0


def sample_interval(t: np.ndarray) -> float:
    """The sample interval [s] of times t [s] (their median step)."""
    return float(np.median(np.diff(t)))


def cutoff(dt: float, wanted_hz: float) -> float:
    """The cut-off [Hz] used at sample interval dt [s]: wanted_hz, at most a quarter of the rate."""
    return min(wanted_hz, 0.25 / dt)


def edge_stretch(cutoff_hz: float) -> float:
    """How much longer than at EDGE_REFERENCE_HZ the low-pass's start-up lasts at cutoff_hz [Hz]."""
    return max(1.0, EDGE_REFERENCE_HZ / cutoff_hz)


def low_pass_derivative(y: np.ndarray, dt: float, cutoff_hz: float) -> np.ndarray:
    """d y / d t of samples y at interval dt [s]: y low-passed at cutoff_hz [Hz], zero-phase, then
    4th-order central differences (2nd order at the two outermost samples)."""
    import scipy.signal  # here: `dampnet --help` imports the data package

    y = np.asarray(y, dtype=np.float64)
    sos = scipy.signal.butter(ORDER, cutoff_hz, fs=1.0 / dt, output="sos")
    pad = int(round(4 * EDGE_S * edge_stretch(cutoff_hz) / dt))
    z = scipy.signal.sosfiltfilt(sos, y, padtype="odd", padlen=min(y.size - 1, pad))
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
    each end a Savitzky-Golay derivative (see the module doc; both spans stretched by edge_stretch
    below EDGE_REFERENCE_HZ)."""
    import scipy.signal

    y = np.asarray(y, dtype=np.float64)
    dt = sample_interval(t)
    fc = cutoff(dt, cutoff_hz)
    d = low_pass_derivative(y, dt, fc)
    stretch = edge_stretch(fc)                           # a slower cut-off: longer ends, a wider fit
    n = min(int(round(ACCEL_EDGE_S * stretch / dt)), y.size // 2)
    window = int(round(EDGE_WINDOW_S * stretch / dt)) | 1          # odd, centred
    if n and window > EDGE_POLYORDER + 1 and y.size >= window:
        edge = scipy.signal.savgol_filter(y, window, EDGE_POLYORDER, deriv=1, delta=dt, mode="interp")
        d[:n], d[-n:] = edge[:n], edge[-n:]
    return d


def content_frequency(y: np.ndarray, dt: float, share: float = CONTENT_SHARE) -> float:
    """The frequency [Hz] below which `share` of the power of samples y (at interval dt [s], mean
    removed, Hann-windowed) lies: a sine's own frequency, a broadband record's upper band."""
    y = np.asarray(y, dtype=np.float64)
    if y.size < 4:
        return 0.0
    power = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size))) ** 2
    total = np.cumsum(power)
    if not np.isfinite(total[-1]) or total[-1] <= 0.0:      # constant (or non-finite): no content
        return 0.0
    return float(np.fft.rfftfreq(y.size, dt)[np.searchsorted(total, share * total[-1])])


def acceleration_cutoff(velocity: np.ndarray, dt: float) -> float:
    """The cut-off [Hz] for the acceleration of one test's velocity [m/s] at interval dt [s]: from
    its content (CONTENT_FACTOR x content_frequency) between MIN_CUTOFF_HZ and
    ACCELERATION_CUTOFF_HZ, at most a quarter of the rate; ACCELERATION_CUTOFF_HZ when
    CONTENT_FACTOR is None."""
    ceiling = cutoff(dt, ACCELERATION_CUTOFF_HZ)
    if CONTENT_FACTOR is None:
        return ceiling
    return float(min(max(CONTENT_FACTOR * content_frequency(velocity, dt), MIN_CUTOFF_HZ), ceiling))


def acceleration_of_motion(y: np.ndarray, t: np.ndarray, order: int = 1) -> tuple[np.ndarray, float]:
    """(acceleration [m/s^2] at times t [s] of velocity y [m/s] (order 1), or of displacement y [m]
    (order 2: the derivative of its velocity), every sample kept; the cut-off [Hz] used)."""
    if order == 2:
        y = smooth_derivative(y, t, VELOCITY_CUTOFF_HZ)
    fc = acceleration_cutoff(y, sample_interval(t))
    return smooth_derivative(y, t, fc), fc


def acceleration_method(bandwidths_hz) -> dict:
    """The acceleration's method in words and its bandwidths [Hz] (each test's cut-off, sorted,
    distinct): for a dataset's and a model's record."""
    rule = (f"at {ACCELERATION_CUTOFF_HZ:g} Hz (at most a quarter of the rate)" if CONTENT_FACTOR is None else
            f"at {CONTENT_FACTOR:g}x the frequency below which {100 * CONTENT_SHARE:g} % of the test's velocity "
            f"power lies, {MIN_CUTOFF_HZ:g} to {ACCELERATION_CUTOFF_HZ:g} Hz (at most a quarter of the rate)")
    return {"method": f"zero-phase Butterworth low-pass of the velocity (order {ORDER}, scipy.signal.sosfiltfilt) "
                      f"{rule}, 4th-order central differences; Savitzky-Golay (degree {EDGE_POLYORDER}, "
                      f"{1000 * EDGE_WINDOW_S:g} ms) within {1000 * ACCEL_EDGE_S:g} ms of each end",
            "bandwidth_hz": sorted({round(float(b), 1) for b in bandwidths_hz})}
