"""Roads: ISO 8608 PSD level and RMS, determinism, the thesis rough road, sweep, impulse, CSV errors."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy.signal import welch

from dampnet.sim.roads import (ISO_BAND, ISO_CLASSES, Road, RoadError, bump, impulse, iso8608,
                           iso_band_variance, iso_class_bounds, read_profile_csv, sine_sweep,
                           sweep_frequency, thesis_rough_road)
from dampnet.recipes.roads import build as make_road   # roads by name (the registry)

# Tolerance for the Welch-estimated PSD level: the fitted Gd(n0) within 15 % of the class value.
# (Deterministic amplitudes make the estimate's scatter small: what remains is Hann leakage and
# the per-bin average of a -2 power law.)
PSD_LEVEL_TOL = 0.15


@pytest.mark.parametrize("cls", list("ABCDEFGH"))
def test_iso8608_psd_level_and_rms(cls):
    road = iso8608(cls, length_m=1000.0, dx=0.05, seed=3)
    g = ISO_CLASSES[cls]
    # RMS equals the analytic integral of Gd over the band (closed form, independent of the synthesis).
    rms = float(np.sqrt(np.mean(road.z[:-1] ** 2)))
    assert rms == pytest.approx(math.sqrt(iso_band_variance(g, ISO_BAND)), rel=1e-6)
    # An independent PSD estimate (Welch, 100 m Hann segments) fitted to Gd(n0) (n/n0)^-2 over
    # 0.05-2 cycle/m in log space.
    n, p = welch(road.z[:-1], fs=1.0 / 0.05, nperseg=2000)
    sel = (n >= 0.05) & (n <= 2.0)
    level = float(np.exp(np.mean(np.log(p[sel] * (n[sel] / 0.1) ** 2))))
    assert level == pytest.approx(g, rel=PSD_LEVEL_TOL)
    lo, hi = iso_class_bounds(cls)
    assert lo <= level < hi
    # Slope of the log-log PSD is the waviness -2 (within 0.1).
    slope = np.polyfit(np.log(n[sel]), np.log(p[sel]), 1)[0]
    assert slope == pytest.approx(-2.0, abs=0.1)


def test_iso8608_same_seed_same_road_other_seed_other_road():
    a, b, c = iso8608("D", seed=7), iso8608("D", seed=7), iso8608("D", seed=8)
    np.testing.assert_array_equal(a.z, b.z)
    assert not np.allclose(a.z, c.z)
    assert a.meta["seed"] == 7


def test_iso8608_is_periodic_and_classes_scale_by_four():
    a = iso8608("B", length_m=100.0, seed=1)
    assert a.z[-1] == a.z[0]
    b = iso8608("C", length_m=100.0, seed=1)
    np.testing.assert_allclose(b.z, 2.0 * a.z, rtol=1e-12, atol=1e-15)   # x4 PSD = x2 amplitude


def test_thesis_rough_road():
    r = thesis_rough_road(seed=0)
    assert r.length == pytest.approx(184.0)
    n = (r.x.size - 1) // 2
    assert float(np.sqrt(np.mean(r.z[:n] ** 2))) == pytest.approx(0.016, rel=1e-9)
    np.testing.assert_array_equal(r.z[:n], r.z[n:2 * n])      # concatenated once
    assert r.meta["iso_class_equivalent"] == "C"
    s10, s20 = r.sample(1e-3, speed=10.0), r.sample(1e-3, speed=20.0)
    assert s10.t[-1] == pytest.approx(18.4, abs=1e-3) and s20.t[-1] == pytest.approx(9.2, abs=1e-3)


def test_sine_sweep_frequency_law_and_amplitude():
    road = sine_sweep(amplitude_m=0.005, f0=0.5, f1=20.0, rate_oct_s=0.2)
    m = road.meta
    assert m["sweep_s"] == pytest.approx(math.log2(40.0) / 0.2)
    assert np.max(np.abs(road.z)) == pytest.approx(0.005, rel=1e-3)
    # Zero crossings give the instantaneous frequency: compare with f0 2^(r t) mid-sweep.
    t, z = road.x, road.z
    sgn = np.signbit(z)
    idx = np.flatnonzero(sgn[1:] != sgn[:-1])
    tc = t[idx]
    tc = tc[(tc > m["pre_s"] + 1) & (tc < m["pre_s"] + m["sweep_s"] - 1)]
    f_est = 0.5 / np.diff(tc)
    f_law = sweep_frequency(0.5 * (tc[1:] + tc[:-1]) - m["pre_s"], 0.5, 20.0, 0.2)
    np.testing.assert_allclose(f_est, f_law, rtol=0.02)
    assert f_law.min() < 0.7 and f_law.max() > 17.0


def test_impulse_and_bump():
    r = impulse(height_m=0.04, duration_s=0.05, start_s=0.5, total_s=2.0)
    assert np.max(r.z) == pytest.approx(0.04, rel=1e-6)
    assert r.z[r.x < 0.5].max() == 0 and r.z[r.x > 0.55].max() == 0
    b = bump(height_m=0.03, length_m=0.5)
    s = b.sample(1e-3, speed=10.0)
    hi = s.t[s.z > 1e-9]
    assert hi[-1] - hi[0] == pytest.approx(0.05, abs=2e-3)     # 0.5 m at 10 m/s


def test_csv_round_trip_and_errors(tmp_path):
    r = iso8608("C", length_m=30.0, seed=2)
    p = tmp_path / "road.csv"
    r.to_csv(p)
    back = read_profile_csv(p)
    np.testing.assert_allclose(back.z, r.z, atol=1e-9)
    np.testing.assert_allclose(back.x, r.x, atol=1e-6)
    assert make_road(str(p)).name == "road.csv"

    cases = {
        "distance_m,height\n0,0\n1,0\n": "no column 'elevation_m'",
        "distance_m,elevation_m\n0,0\n1,abc\n": ":3: column elevation_m: 'abc' is not a number",
        "distance_m,elevation_m\n0,0\n1,nan\n": ":3: column elevation_m: 'nan' is not finite",
        "distance_m,elevation_m\n0,0\n1,0\n1,0\n": ":4: column distance_m: 1.0 does not increase",
        "distance_m,elevation_m\n0,0\n": "at least 2 data rows",
        "": "empty file",
        "distance_m,elevation_m\n0,0\n1,\n": ":3: column elevation_m: empty cell",
    }
    for i, (text, msg) in enumerate(cases.items()):
        q = tmp_path / f"bad{i}.csv"
        q.write_text(text)
        with pytest.raises(RoadError, match=msg.replace("(", r"\(").replace(".", r"\.")):
            read_profile_csv(q)
        assert f"bad{i}.csv" in str(pytest.raises(RoadError, read_profile_csv, q).value)


def test_nonsensical_roads_are_refused():
    with pytest.raises(RoadError, match="not finite at index 2"):
        Road("r", "spatial", [0, 1, 2, 3], [0, 0, float("nan"), 0])
    with pytest.raises(RoadError, match="increase strictly"):
        Road("r", "spatial", [0, 1, 1, 3], [0, 0, 0, 0])
    road = Road("short", "spatial", [0.0, 0.001], [0.0, 0.0])
    with pytest.raises(RoadError, match="shorter than one time step"):
        road.sample(1e-3, speed=10.0)
    with pytest.raises(RoadError, match="time step dt"):
        iso8608("A", length_m=20).sample(0.0, speed=10.0)
    with pytest.raises(RoadError, match="speed"):
        iso8608("A", length_m=20).sample(1e-3, speed=-1.0)
    with pytest.raises(RoadError, match="give a speed"):
        iso8608("A", length_m=20).sample(1e-3)
    with pytest.raises(RoadError, match="A-H"):
        iso8608("Z")
    with pytest.raises(RoadError, match="unknown road"):
        make_road("cobbles")


@pytest.mark.parametrize("road, param", [
    ("rough:rms_m=1e300", "rms_m"), ("rough:rms_m=1e200", "rms_m"), ("rough:rms_m=nan", "rms_m"),
    ("sweep:rate_oct_s=1e-7", "rate_oct_s"), ("sweep:rate_oct_s=1e9", "rate_oct_s"),
    ("iso:length_m=4e6", "length_m"), ("impulse:duration_s=1e-300", "duration_s"),
    ("bump:width_m=1e-12", "width_m"), ("rough:seed=-1", "seed"),
])
def test_a_road_parameter_out_of_range_is_refused_naming_it_before_building(road, param):
    """Issue 49, items 7, 8, 10, 18: overflow tracebacks, MemoryErrors after minutes, all-zero runs
    and numpy's bare `expected non-negative integer` become one RoadError naming the road, the
    parameter, its range and unit, raised by parsing, before any profile is built. Milliseconds."""
    from dampnet.recipes import roads

    with pytest.raises(RoadError, match=rf"road {re.escape(repr(road))}: {param}: expected (.* to |at least )"):
        roads.parse(road)


@pytest.mark.parametrize("road", ["iso:class=C,class=D", "rough:seed=1,seed=2", "iso:C,class=D"])
def test_a_road_parameter_given_twice_is_refused(road):
    """Issue 49, item 13: the last of repeated keys silently won. Milliseconds."""
    from dampnet.recipes import roads

    with pytest.raises(RoadError, match="given twice"):
        roads.parse(road)


def test_every_default_road_parameter_is_in_its_own_range():
    from dampnet.recipes import roads

    for name in roads.names():
        kind = roads.get(name)
        for p in kind.params:
            assert p.read(p.default, name) == p.default, (name, p.name)


def test_a_road_csv_with_a_bom_is_read_and_one_not_in_utf8_is_named(tmp_path):
    """Issue 49, item 18: a spreadsheet's UTF-8 BOM hid the distance_m column, and a Latin-1 file
    was a UnicodeDecodeError traceback; a FIFO is refused, not waited on. Milliseconds."""
    import os

    from dampnet.sim.roads import read_profile_csv

    body = "distance_m,elevation_m\n" + "".join(f"{0.1 * i:.1f},{0.001 * (i % 7):.3f}\n" for i in range(100))
    plain, bom = tmp_path / "plain.csv", tmp_path / "bom.csv"
    plain.write_text(body)
    bom.write_bytes(b"\xef\xbb\xbf" + body.encode())
    np.testing.assert_array_equal(read_profile_csv(bom).x, read_profile_csv(plain).x)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(("# d\xe9nivel\u00e9\n" + body).encode("latin-1"))
    with pytest.raises(RoadError, match=r"latin.csv: byte \d+: not UTF-8 CSV text"):
        read_profile_csv(latin)
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    with pytest.raises(RoadError, match="fifo.csv: is not a regular file"):
        read_profile_csv(fifo)
