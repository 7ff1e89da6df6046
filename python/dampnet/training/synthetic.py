"""A synthetic damper-like data set with known structure, for benchmarks and tests.

Sinusoidal dyno tests (displacement A sin(2 pi f t)) at several frequencies,
amplitudes and valve voltages. The force [N] is a digressive, asymmetric
(rebound stronger than compression), voltage-dependent curve in velocity,
plus a small acceleration (inertia/compliance) term and Gaussian noise.
"""

from __future__ import annotations

import numpy as np


def damper_force(v: np.ndarray, a: np.ndarray, volt: np.ndarray) -> np.ndarray:
    """Noise-free force [N] for velocity v [m/s], acceleration a [m/s^2], voltage volt [V]."""
    c_low = 3000.0 + 1500.0 * volt  # low-speed damping [N s/m], grows with voltage
    v_knee = 0.08 + 0.02 * volt  # blow-off knee [m/s]
    c_high = 600.0 + 100.0 * volt  # high-speed damping [N s/m]
    f = c_low * v_knee * np.tanh(v / v_knee) + c_high * v
    f = np.where(v < 0, 0.55 * f, f)  # compression softer than rebound
    return f + 2.0 * a  # 2 kg effective moving mass


def synthetic_dyno(n_tests: int = 180, samples_per_test: int = 500, noise: float = 0.01,
                   seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """X [n_tests * samples_per_test, 3] (velocity m/s, acceleration m/s^2, voltage V), force y [N].

    Tests cycle through frequencies 0.25-6 Hz, stroke amplitudes 5-40 mm and
    voltages 0-4.5 V; `noise` is the noise standard deviation relative to the
    force range.
    """
    rng = np.random.default_rng(seed)
    freqs = np.array([0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0])
    amps = np.array([0.005, 0.01, 0.02, 0.04])
    volts = np.linspace(0.0, 4.5, 7)
    rows = []
    for i in range(n_tests):
        f = freqs[i % len(freqs)]
        amp = amps[(i // len(freqs)) % len(amps)]
        volt = volts[(i // (len(freqs) * len(amps))) % len(volts)]
        t = np.linspace(0.0, 2.0 / f, samples_per_test, endpoint=False)  # two cycles
        w = 2 * np.pi * f
        v = amp * w * np.cos(w * t)
        a = -amp * w * w * np.sin(w * t)
        rows.append(np.stack([v, a, np.full_like(t, volt)], axis=1))
    X = np.concatenate(rows)
    y = damper_force(X[:, 0], X[:, 1], X[:, 2])
    y = y + noise * np.ptp(y) * rng.standard_normal(len(y))
    return X, y
