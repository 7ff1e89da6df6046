"""The two real MR-damper data sets in ../shared/data load as datasets with the ranges their READMEs state."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.data.real import LABCONTROL, UTFSM, load_labcontrol, load_utfsm, shared_data_dir

ROOT = shared_data_dir()
pytestmark = pytest.mark.skipif(not (ROOT / UTFSM).is_dir() or not (ROOT / LABCONTROL).is_dir(),
                                reason=f"real data not present at {ROOT} (set DAMPNET_SHARED_DATA)")


def test_utfsm_loads_30_current_controlled_tests_with_readme_ranges():
    ds = load_utfsm()
    assert len(ds.tests) == 30
    grid = {(round(t.amplitude_m * 1e3), t.frequency_hz) for t in ds.tests}
    assert grid == {(10, 1.0), (25, 0.1), (25, 0.25), (25, 0.5), (2, 5.0), (5, 3.0)}
    assert {t.control_nominal for t in ds.tests} == {0.0, 0.25, 0.5, 0.75, 1.0}
    for t in ds.tests:
        assert t.control_name == "current"
        assert np.all(t.channels["current"] == t.control_nominal)
        expect_dt = 0.001 if t.frequency_hz in (1.0, 3.0) else 0.005           # README sample times
        assert t.dt == pytest.approx(expect_dt, rel=1e-6)
        # displacement in metres: peak-to-peak about twice the named amplitude (mm in the file)
        assert 1.2 * t.amplitude_m < np.ptp(t.channels["displacement"]) < 2.2 * t.amplitude_m
        peak = np.max(np.abs(t.channels["force"]))
        # README: "~180-220 N at 0 A, ~1360-1550 N at 1 A"; '~' read as +-10 % (the 0.1 Hz test is lowest)
        if t.control_nominal == 0.0:
            assert 0.9 * 180 < peak < 1.1 * 220
        if t.control_nominal == 1.0:
            assert 0.9 * 1360 < peak < 1.1 * 1550


def test_labcontrol_loads_the_series_with_an_inferred_voltage():
    ds = load_labcontrol()
    volts = {t.control_nominal for t in ds.tests}
    assert volts == {0.0, 0.8712, 1.98, 3.212}
    assert len(ds.tests) >= 30 and ds.meta["skipped"]
    for t in ds.tests:
        x_mm = t.channels["displacement"] * 1e3
        assert -25 < x_mm.min() and x_mm.max() < 26                     # README: position mm, 0-25
        assert np.max(np.abs(t.channels["force"])) < 1100               # README: up to ~1000 N
        assert t.dt == pytest.approx(0.01, rel=1e-6)
        assert 0.4 < t.frequency_hz < 2.5                               # README: 0.46-2.4 Hz
        # velocity is the derivative of position (README: corr ~0.999)
        d = np.gradient(t.channels["displacement"], t.time)
        assert np.corrcoef(d, t.channels["velocity"])[0, 1] > 0.98
    a = [t for t in ds.tests if t.control_nominal == 3.212]
    z = [t for t in ds.tests if t.control_nominal == 0.0]
    # more voltage, more MR damping: series A forces are higher than the 0 V series
    assert min(np.ptp(t.channels["force"]) for t in a) > max(np.ptp(t.channels["force"]) for t in z)


def test_load_real_through_load_dataset_style_options():
    ds = load_utfsm(force_positive="compression")
    ref = load_utfsm()
    np.testing.assert_array_equal(ds.tests[0].channels["force"], -ref.tests[0].channels["force"])
