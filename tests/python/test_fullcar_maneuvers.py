"""The full vehicle's tests (dampnet.sim.full_car.maneuvers, metrics, runs, study) and `dampnet vehicle`:
the ISO 3888-1 geometry against the standard's numbers, the sweep, the rear wheels' delay, the
tracks' coherence, cone counting on constructed paths, one run of each test, the CLI."""

import json

import numpy as np
import pytest

from dampnet import _core
from dampnet.cli import main
from dampnet.sim.full_car import maneuvers, metrics, runs, study
from dampnet.recipes import maneuvers as recipes
from dampnet.sim.dampers import linear_spec, lookup_spec
from dampnet.sim.roads import RoadError, sweep_frequency, thesis_rough_road


def test_iso3888_lanes_follow_the_standard():
    """ISO 3888-1:2018: sections 15, 30, 25, 25, 15 m; lane widths 1.1 w + 0.25, w + 1,
    1.3 w + 0.25; the offset lane's right cone line 3.5 m left of the entry lane's."""
    w = 1.85
    lanes = maneuvers.iso3888_lanes(w)
    assert [round(s["x1"] - s["x0"], 9) for s in lanes] == [15.0, 30.0, 25.0, 25.0, 15.0]
    assert lanes[0]["x0"] == 0.0 and lanes[-1]["x1"] == 110.0
    np.testing.assert_allclose([lanes[0]["width"], lanes[2]["width"], lanes[4]["width"]],
                               [1.1 * w + 0.25, w + 1.0, 1.3 * w + 0.25])
    np.testing.assert_allclose(lanes[2]["y_right"] - lanes[0]["y_right"], 3.5)
    np.testing.assert_allclose(lanes[4]["y_right"], lanes[0]["y_right"])
    np.testing.assert_allclose(lanes[0]["y_centre"], 0.0)
    cones = maneuvers.iso3888_cones(w)
    assert cones.shape == (6 * maneuvers.CONES_PER_LINE, 2)
    x, y = maneuvers.iso3888_path(w)
    assert len(x) <= 256 and np.all(np.diff(x) > 0)
    half = w / 2 + maneuvers.DLC_PATH_MARGIN_M
    for sec in (lanes[0], lanes[2], lanes[4]):  # the car's width and the margin inside each lane
        inside = (x >= sec["x0"]) & (x <= sec["x1"])
        assert np.all(y[inside] - half >= sec["y_right"] - 1e-7), sec["name"]
        assert np.all(y[inside] + half <= sec["y_left"] + 1e-7), sec["name"]
    np.testing.assert_allclose(y[x <= -maneuvers.DLC_RUN_IN_M / 2], lanes[0]["y_centre"], atol=1e-7)
    np.testing.assert_allclose(y[-3:], y[-1], atol=1e-9)   # straight at the end
    kappa = maneuvers.path_curvature(x, y)
    assert np.max(np.abs(np.diff(kappa[1:-1]) / np.diff(x[1:-1]))) <= maneuvers.DLC_PATH_CURVATURE_RATE * (1 + 1e-6)
    # a path through the lanes needs far less than the half-cosine ramps over the 30 m and 25 m
    # gaps between the lanes' centres (peak pi^2 D / (2 L^2): 3.5 m over 25 m, 0.0276 1/m); and
    # any path with the car in the entry lane at 15 m and in the offset lane at 45 m shifts
    # D >= (y_right,offset + half) - (y_left,entry - half) in at most 30 m + both lanes:
    # kappa >= 4 D / (15 + 30 + 25)^2 (bang-bang over the whole 70 m, a loose lower bound)
    D = (lanes[2]["y_right"] + half) - (lanes[0]["y_left"] - half)
    assert 4 * D / 70.0**2 < np.max(np.abs(kappa)) < 0.3 * np.pi**2 * 3.5 / (2 * 25.0**2)
    with pytest.raises(RoadError, match="vehicle width"):
        maneuvers.iso3888_lanes(0.0)


def _fake_run(x, y, psi=None):
    """A run's arrays with the CG at (x, y) [m] (lanes' frame, the run starting at x = -60)."""
    n = len(x)
    state = np.zeros((n, len(_core.FULLCAR_STATE_NAMES)))
    state[:, _core.FULLCAR_STATE_NAMES.index("x_pos")] = np.asarray(x) + maneuvers.DLC_RUN_IN_M
    state[:, _core.FULLCAR_STATE_NAMES.index("y_pos")] = y
    if psi is not None:
        state[:, _core.FULLCAR_STATE_NAMES.index("psi")] = psi
    return {"state": state}


def test_cones_hit_on_constructed_paths():
    """Straight along y = 0: no cone (the vehicle's half width, 0.95 m, clears every line).
    Straight along y = 1.17 m: the entry lane's left line (at +1.17 m) and the exit lane's left
    line (+1.55 m, 0.38 m away) are hit, 2 x 5 cones; a car yawed 90 degrees at the entry lane's
    centre spans 5.35 m across it and hits one cone on each side."""
    man = maneuvers.dlc(1e-3, 80.0)
    params = {"a": 1.5, "b": 1.75}
    x = np.linspace(-60, 170, 5000)
    assert metrics.cones_hit(_fake_run(x, np.zeros_like(x)), man, params) == []
    hit = metrics.cones_hit(_fake_run(x, np.full_like(x, 1.17)), man, params)
    cones = np.asarray(man.meta["cones"])
    assert len(hit) == 10
    assert set(np.round(cones[hit, 1], 2)) == {1.17, 1.55}
    hit = metrics.cones_hit(_fake_run([7.5], [0.0], [np.pi / 2]), man, params)
    assert sorted(np.round(cones[hit, 1], 2)) == [-1.17, 1.17]


def test_bsst_sweeps_all_wheels_in_heave_and_front_against_rear_in_pitch():
    heave = maneuvers.bsst(1e-3, "heave", rate_oct_s=1.0)
    pitch = maneuvers.bsst(1e-3, "pitch", rate_oct_s=1.0)
    assert heave.speed == 0.0 and heave.path is None
    for k in range(1, 4):
        np.testing.assert_array_equal(heave.road[:, k], heave.road[:, 0])
    np.testing.assert_array_equal(pitch.road[:, 2], -pitch.road[:, 0])
    np.testing.assert_array_equal(pitch.road[:, 1], pitch.road[:, 0])
    # the instantaneous frequency from the zero crossings follows the log sweep's law
    z, t = heave.road[:, 0], heave.t
    pre = heave.meta["pre_s"]
    cross = t[1:][(np.sign(z[1:]) != np.sign(z[:-1])) & (t[1:] > pre + 0.5) & (t[1:] < pre + 4.5)]
    f_est = 0.5 / np.diff(cross)
    mid = 0.5 * (cross[1:] + cross[:-1]) - pre
    np.testing.assert_allclose(f_est, sweep_frequency(mid, rate_oct_s=1.0), rtol=0.03)
    with pytest.raises(RoadError, match="mode"):
        maneuvers.bsst(mode="roll")


def test_rough_road_rear_wheels_follow_the_front_a_wheelbase_later():
    """At 117 km/h (32.5 m/s) a 3.25 m wheelbase is 0.1 s: 100 steps of 1 ms. The left and
    right tracks are correlated by the stated coherence."""
    man = recipes.build("road", 1e-3, {"speed_kmh": 117.0, "road": "thesis"}, {"a": 1.5, "b": 1.75})
    d = 100
    np.testing.assert_allclose(man.road[d:, 2], man.road[:-d, 0], atol=1e-4 * np.std(man.road[:, 0]))
    np.testing.assert_allclose(man.road[d:, 3], man.road[:-d, 1], atol=1e-4 * np.std(man.road[:, 1]))
    rho = np.corrcoef(man.road[:, 0], man.road[:, 1])[0, 1]
    assert abs(rho - maneuvers.TRACK_COHERENCE) < 0.15
    assert man.meta["rear_delay_s"] == pytest.approx(0.1)
    with pytest.raises(RoadError, match="coherence"):
        maneuvers.rough_road(thesis_rough_road(), coherence=1.5)


def test_each_test_runs_and_the_study_compares_models():
    """A linear damper and a two-level lookup table through every test (shortened): finite
    metrics of the right kind, the lane change steers the car across (a_y of several m/s^2),
    and the study's table holds every model at every damping."""
    import types

    table = types.SimpleNamespace(velocities=np.array([-1.0, 0.0, 1.0]), voltages=np.array([0.0, 5.0]),
                                  forces=np.array([[-3000.0, 0.0, 3000.0], [-800.0, 0.0, 800.0]]))
    specs = [linear_spec(2500.0, "linear"), lookup_spec(table, "lookup")]
    tests = {"bsst_heave": maneuvers.bsst(2e-3, rate_oct_s=2.0), "dlc": maneuvers.dlc(2e-3, 80.0),
             "road_thesis": recipes.build("road", 2e-3)}
    tests["road_thesis"].road = tests["road_thesis"].road[:1500]
    tests["road_thesis"].road_rate = tests["road_thesis"].road_rate[:1500]
    tests["road_thesis"].steer = tests["road_thesis"].steer[:1500]
    res = recipes.run_study(specs, tests, damping=("low", "high"))   # each test's metrics: its recipe
    for test, by_d in res["results"].items():
        for d in ("low", "high"):
            assert set(by_d[d]) == {"linear", "lookup"}
    dlc = res["results"]["dlc"]["low"]["linear"]
    assert 2.0 < dlc["a_y_peak_m_s2"] < 12.0 and dlc["cones"] == 30
    bs = res["results"]["bsst_heave"]
    # the table's high setting (u = 0 V: 3000 N at 1 m/s) damps the body more than its low one
    assert bs["high"]["lookup"]["acc_rms_m_s2"] != bs["low"]["lookup"]["acc_rms_m_s2"]
    assert "bsst_heave" in study.text_table(res)


def test_vehicle_cli_writes_metrics_and_plot(tmp_path, capsys):
    out = tmp_path / "v"
    assert main(["vehicle", "linear:2500", "--test", "dlc", "--speed", "80", "--dt", "0.002",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "cones hit" in text and "running dlc" in text
    meta = json.loads((out / "metrics.json").read_text())
    assert meta["schema"] == "dampnet.vehicle/1" and meta["metrics"]["a_y_peak_m_s2"] > 2.0
    assert (out / "vehicle.png").stat().st_size > 10_000
    assert np.load(out / "run.npz")["state"].shape[1] == len(_core.FULLCAR_STATE_NAMES)
    # an existing run is kept unless --force
    assert main(["vehicle", "linear:2500", "--test", "bsst", "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert json.loads((out / "metrics.json").read_text())["test"] == "dlc"


@pytest.mark.parametrize("args,message", [
    (["--test", "bsst", "--speed", "50"], "four-post rig"),
    (["--test", "road", "--profile", "Z"], "ISO 8608 class"),
    (["--test", "road", "--road", "cobbles"], "--road: unknown road 'cobbles'"),
    (["--test", "road", "--road", "iso:C", "--profile", "C"], "give --road only"),
    (["--test", "dlc", "--road", "iso:C"], "--road: dlc does not take it"),
    (["--test", "dlc", "--profile", "C"], "--profile: dlc does not take a road"),
    (["--test", "dlc", "--speed", "-5"], "--speed: expected a finite number in (0, 360] km/h, got -5.0"),
    (["--dt", "0.5"], "--dt"),
])
def test_vehicle_cli_bad_input(tmp_path, capsys, args, message):
    assert main(["vehicle", "linear:2500", *args, "--out", str(tmp_path / "v")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and message in err


@pytest.mark.parametrize("argv, road, seed, kmh, want", [
    (["--profile", "thesis"], "rough", 0, 60.0, (0.44975496713146695, 0.35158489779918434, 3.0536080831551278)),
    (["--profile", "C", "--seed", "2", "--speed", "72"], "iso:C", 2, 72.0,
     (0.4572427347863982, 0.36632627151207914, 4.480160882312133)),
])
def test_the_registry_road_keeps_the_old_thesis_and_iso_results(tmp_path, argv, road, seed, kmh, want):
    """Issue 52: the full car's road comes from the road registry now; `vehicle --test road
    --profile thesis` (and ISO C) are unchanged: the four wheel tracks are the old construction's
    bit for bit (left the profile at the seed, right 0.6 left + 0.8 the profile at seed + 1, the
    rear 3.25 m behind on the periodic profile), and the metrics of a 1500 N s/m damper at low
    damping are the numbers the old `--profile` gave before the change (commit 2e72b5a). Cost: 0.5 s each."""
    out = tmp_path / "v"
    assert main(["vehicle", "linear:1500", "--test", "road", *argv, "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())["metrics"]
    got = (m["acc_rms_m_s2"], m["acc_wk_rms_m_s2"], m["roll_rate_rms_deg_s"])
    np.testing.assert_allclose(got, want, rtol=1e-9)
    from dampnet.sim.roads import iso8608

    make = (lambda s: thesis_rough_road(seed=s)) if road == "rough" else (lambda s: iso8608("C", seed=s))
    left, other = make(seed), make(seed + 1)
    right = 0.6 * left.z + 0.8 * other.z
    v = kmh / 3.6
    t = np.arange(int(left.length / v / 1e-3) + 1) * 1e-3
    xf, xr = v * t, np.mod(v * t - 3.25, left.length)
    old = np.stack([np.interp(xf, left.x, left.z), np.interp(xf, left.x, right),
                    np.interp(xr, left.x, left.z), np.interp(xr, left.x, right)], axis=1)
    assert np.array_equal(np.load(out / "run.npz")["road"], old)
