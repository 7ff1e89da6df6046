"""Ride metrics: Wk against ISO 2631-1 Table 3, transmissibility against an analytic quarter car, simple metrics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lsim, sosfreqz

from dampnet.sim.ride import (WK_TABLE, peak_to_rms, ride_metrics, rms, transmissibility, wk_analog, wk_sos,
                          wk_weighted)
from dampnet.sim.roads import sine_sweep

FREQS = np.array(sorted(WK_TABLE))
TABLE = np.array([WK_TABLE[f] for f in FREQS]) / 1000.0

# Stated tolerances. Analog Wk vs ISO 2631-1 Table 3 (three significant figures): 0.5 %.
# Digital Wk at 1 kHz vs Table 3: 1 % up to 50 Hz, 2 % up to 80 Hz, 5 % at 100 Hz.
ANALOG_TOL = 0.005


def test_analog_wk_matches_the_standard_table():
    got = np.abs(wk_analog(FREQS))
    np.testing.assert_allclose(got, TABLE, rtol=ANALOG_TOL)


@pytest.mark.parametrize("fmax,tol", [(50.0, 0.01), (80.0, 0.02), (100.0, 0.05)])
def test_digital_wk_at_1khz_matches_the_table(fmax, tol):
    sel = FREQS <= fmax
    _, h = sosfreqz(wk_sos(1000.0), worN=FREQS[sel], fs=1000.0)
    np.testing.assert_allclose(np.abs(h), TABLE[sel], rtol=tol)


@pytest.mark.parametrize("f", [1.0, 5.0, 16.0])
def test_wk_weighted_sinusoid_rms_is_scaled_by_the_table_value(f):
    fs = 1000.0
    t = np.arange(0, 30.0, 1 / fs)
    a = np.sin(2 * np.pi * f * t)
    w = wk_weighted(a, fs)
    steady = t > 10.0                       # past the 0.4 Hz high-pass transient
    assert rms(w[steady]) / rms(a[steady]) == pytest.approx(WK_TABLE[f] / 1000, rel=0.01)


def test_wk_refuses_low_sample_rates():
    with pytest.raises(ValueError, match="250 Hz"):
        wk_sos(100.0)


def linear_quarter_car(ms=700.0, mu=40.0, ks=15e3, kt=200e3, c=1500.0):
    """Thesis eq. (13)-(14) with a linear damper; state (zs, vs, zu, vu), input road zr."""
    a = np.array([[0, 1, 0, 0],
                  [-ks / ms, -c / ms, ks / ms, c / ms],
                  [0, 0, 0, 1],
                  [ks / mu, c / mu, -(ks + kt) / mu, -c / mu]])
    b = np.array([[0], [0], [0], [kt / mu]])
    cm = np.eye(4)
    return a, b, cm, np.zeros((4, 1))


def analytic_zs_over_zr(f, ms=700.0, mu=40.0, ks=15e3, kt=200e3, c=1500.0):
    s = 2j * np.pi * f
    ps = ms * s**2 + c * s + ks
    pu = mu * s**2 + c * s + ks + kt
    return kt * (c * s + ks) / (ps * pu - (c * s + ks) ** 2)


@pytest.mark.parametrize("rate", [0.1, 0.2])
def test_transmissibility_of_a_sweep_matches_the_analytic_quarter_car(rate):
    fs = 500.0
    road = sine_sweep(amplitude_m=0.005, rate_oct_s=rate, fs=5000.0)
    s = road.sample(1 / fs)
    _, y, _ = lsim(linear_quarter_car(), s.z, s.t)       # scipy's exact LTI response, not our loop
    tr = transmissibility(s.z, y[:, 0], fs, fmin=0.6, fmax=18.0)
    f, h = tr["f_hz"], tr["magnitude"]
    ref = np.abs(analytic_zs_over_zr(f))
    # Stated tolerance: 1.5 % over 0.6-18 Hz, body-mode peak included (measured 0.6 % / 0.75 %).
    np.testing.assert_allclose(h, ref, rtol=0.015)
    assert abs(f[np.argmax(h)] - f[np.argmax(ref)]) <= 2 * (f[1] - f[0])


def test_welch_transmissibility_of_random_input():
    fs = 200.0
    rng = np.random.default_rng(0)
    t = np.arange(0, 600.0, 1 / fs)
    u = rng.standard_normal(t.size) * 0.01
    _, y, _ = lsim(linear_quarter_car(c=3000.0), u, t)
    tr = transmissibility(u, y[:, 0], fs, fmin=0.3, fmax=15.0, method="welch", seg_s=20.0)
    ref = np.abs(analytic_zs_over_zr(tr["f_hz"], c=3000.0))
    np.testing.assert_allclose(tr["magnitude"], ref, rtol=0.1)
    assert np.all(tr["coherence"] > 0.9)


def test_ride_metrics_of_known_signals():
    fs = 1000.0
    t = np.arange(0, 20.0, 1 / fs)
    zs = 0.01 * np.sin(2 * np.pi * 1.0 * t)
    zu = 0.002 * np.sin(2 * np.pi * 1.0 * t)
    zr = np.zeros_like(t)
    acc = -(2 * np.pi) ** 2 * zs
    m = ride_metrics(t, zs, zu, zr, acc, kt=200e3, ms=700.0, mu=40.0)
    assert m["acc_rms_m_s2"] == pytest.approx((2 * np.pi) ** 2 * 0.01 / np.sqrt(2), rel=1e-3)
    assert m["disp_peak_to_rms"] == pytest.approx(np.sqrt(2), rel=1e-3)
    assert m["travel_rms_m"] == pytest.approx(0.008 / np.sqrt(2), rel=1e-3)
    assert m["travel_max_m"] == pytest.approx(0.008, rel=1e-4)
    assert m["tyre_load_rms_n"] == pytest.approx(200e3 * 0.002 / np.sqrt(2), rel=1e-3)
    assert m["tyre_load_rms_rel"] == pytest.approx(m["tyre_load_rms_n"] / (740 * 9.80665))
    assert m["acc_wk_rms_m_s2"] == pytest.approx(0.482 * m["acc_rms_m_s2"], rel=0.03)
    assert peak_to_rms(np.zeros(5)) == 0.0
