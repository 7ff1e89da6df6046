"""What a test's displacement says about its excitation: a sine (frequency, amplitude) or not.

Used where a test has no manifest saying so: the real data sets (dampnet.data.real) and lab
files read without one (dampnet.data.lab, whose derived manifest records sines by their
frequency and everything else, such as a replayed road, as random content).
"""

from __future__ import annotations

import numpy as np

#: share of the displacement's (mean-removed, Hann-windowed) spectral energy within +-2 bins of
#: its peak above which a test counts as a sine; a replayed road or random test has far less
#: (measured: the quick plan's sines above it; replays of the rough road and of ISO class C at
#: 20 m/s under skyhook, 0.54)
SINE_PURITY = 0.9


def estimate_sine(x: np.ndarray, dt: float) -> tuple[float, float, float]:
    """(frequency [Hz], amplitude [m], purity) of displacement `x` [m] sampled every `dt` [s].

    Frequency: the spectral peak (Hann window); amplitude: half the 1-99 % range (robust to
    spikes); purity: the share of spectral energy within +-2 bins of the peak.
    """
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(all="ignore"):   # absurd values (a corrupt file) give inf, refused below
        x0 = x - np.mean(x)
        spec = np.abs(np.fft.rfft(x0 * np.hanning(len(x0)))) ** 2
    f = np.fft.rfftfreq(len(x0), dt)
    if spec.size < 3 or not np.isfinite(spec).all() or spec[1:].sum() <= 0:
        return 0.0, 0.0, 0.0
    k = 1 + int(np.argmax(spec[1:]))
    purity = float(spec[max(1, k - 2):k + 3].sum() / spec[1:].sum())
    lo, hi = np.percentile(x, [1, 99])
    return float(f[k]), float((hi - lo) / 2), purity


#: a sine test holds its amplitude: the RMS of each quarter of the displacement within this
#: ratio of each other (a bump's decaying ring-out at the body mode is pure but not steady)
STEADY_RATIO = 1.25


def sine_or_none(x: np.ndarray, dt: float) -> tuple[float | None, float | None]:
    """(frequency_hz, amplitude_m) if `x` is a sine (purity >= SINE_PURITY, amplitude steady
    within STEADY_RATIO over the test's quarters), else (None, None)."""
    freq, amp, purity = estimate_sine(x, dt)
    if purity < SINE_PURITY or freq <= 0:
        return None, None
    x0 = np.asarray(x, dtype=np.float64) - np.mean(x)
    rms = [float(np.sqrt(np.mean(q * q))) for q in np.array_split(x0, 4) if q.size]
    if min(rms) <= 0 or max(rms) / min(rms) > STEADY_RATIO:
        return None, None
    return freq, amp
