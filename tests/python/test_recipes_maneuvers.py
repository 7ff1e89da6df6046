"""The manoeuvre recipe (docs/recipes.md, "Manoeuvres"), proved: the doc's block, run as written
from this test (a user's module: a manoeuvre and its own setting, dampnet.recipes.maneuvers),
through `dampnet vehicle` and through a sweep (in-process Dask, so the registration reaches the worker), its setting an option
and a [fullcar] key with its unit and default; unknown names are refused listing the registry's;
the bounce sweep's bsst_* settings work from the command line as in a sweep.

Short runs: a 2 s hump at a 2 ms step, a 2 -> 4 Hz bounce sweep at 1 octave/s."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.recipes import maneuvers
from dampnet.sim.dampers import load_spec
from recipe_tree import run_doc_block

DT = 2e-3
SHORT_BSST = {"bsst_f0_hz": 2.0, "bsst_f1_hz": 4.0, "bsst_rate_oct_s": 1.0}


@pytest.fixture
def hump():
    """docs/recipes.md's manoeuvre recipe, run as written (a user's module); removed after the test.
    Yields the recipe's namespace (its builder and metrics) with the registered entry as "recipe"."""
    namespace = run_doc_block("Manoeuvres")
    try:
        yield {**namespace, "recipe": maneuvers.get("hump")}
    finally:
        maneuvers.unregister("hump")
    assert "hump_height_m" not in maneuvers.SETTINGS and "bsst_f0_hz" in maneuvers.SETTINGS


def vehicle_run(tmp_path, name, *args) -> dict:
    out = tmp_path / name
    assert main(["vehicle", "linear:2500", "--dt", str(DT), "--out", str(out), *args]) == 0
    return json.loads((out / "metrics.json").read_text())


def test_a_manoeuvre_registered_here_runs_in_dampnet_vehicle(hump, tmp_path, capsys):
    low = vehicle_run(tmp_path, "a", "--test", "hump")
    printed = capsys.readouterr().out
    assert "running hump" in printed and "hump_acc_peak_m_s2" in printed    # the headline line
    assert low["test"] == "hump" and low["maneuver"]["test"] == "hump"
    assert low["params"]["speed"] == 10.0 and low["maneuver"]["hump_height_m"] == 0.01     # the defaults
    assert (tmp_path / "a" / "vehicle.png").stat().st_size > 10_000                      # its plot
    high = vehicle_run(tmp_path, "b", "--test", "hump", "--hump-height", "0.02", "--speed", "36")
    # the setting reaches the physics: a linear car on a twice as high hump, about twice the acceleration
    ratio = high["metrics"]["hump_acc_peak_m_s2"] / low["metrics"]["hump_acc_peak_m_s2"]
    assert 1.8 < ratio < 2.2, ratio
    # its setting is refused for another test, its own checked with its unit
    for args, message in ((["--test", "road", "--hump-height", "0.02"], "--hump-height: road does not take it "
                                                                        "(it applies to hump); drop --hump-height"),
                          (["--test", "hump", "--hump-height", "-1"], "--hump-height: expected a finite number > 0 "
                                                                      "[m], got -1.0"),
                          (["--test", "hump", "--mode", "pitch"], "--mode: hump does not take it (it applies to "
                                                                  "bsst); drop --mode")):
        assert main(["vehicle", "linear:2500", *args, "--out", str(tmp_path / "x")]) == 2
        assert message in capsys.readouterr().err, message
    assert not (tmp_path / "x").exists()


def test_a_manoeuvre_registered_here_runs_in_a_sweep(hump, tmp_path):
    import needs

    for module in ("dask.distributed", "pandas", "pyarrow"):
        needs.need_module(module)
    from dask.distributed import Client, LocalCluster

    from dampnet.sweep import parse_spec, run
    from dampnet.sweep.grid import expand

    spec = {"fullcar": {"models": ["linear:2500"], "tests": ["hump", "bsst"], "hump_heights_m": [0.01, 0.02],
                        "dt": DT, **SHORT_BSST}}
    cells = expand(parse_spec(spec))
    assert sorted((c.params["test"], c.params["hump_height_m"]) for c in cells) == \
        [("bsst", None), ("hump", 0.01), ("hump", 0.02)]
    assert all(c.params["speed_kmh"] == 36.0 for c in cells if c.params["test"] == "hump")   # its default
    assert parse_spec({"fullcar": {"tests": "hump"}}).sections["fullcar"].objective == "hump_acc_peak_m_s2"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        df = run(spec, client=client, out=tmp_path / "s", progress=False)
    assert len(df) == 3 and (df["status"] == "ok").all(), df[["status", "error"]]
    spec_ = load_spec("linear:2500")
    for _, row in df[df["test"] == "hump"].iterrows():
        mine = maneuvers.run(spec_, maneuvers.build("hump", DT, {"hump_height_m": row["hump_height_m"]}), "low")
        assert row["hump_acc_peak_m_s2"] == mine["metrics"]["hump_acc_peak_m_s2"]
        assert row["hump_pitch_rate_peak_deg_s"] == mine["metrics"]["hump_pitch_rate_peak_deg_s"]
    bsst = df[df["test"] == "bsst"]
    assert bsst["hump_height_m"].isna().all() and bsst["hump_acc_peak_m_s2"].isna().all()
    assert bsst["acc_rms_m_s2"].notna().all()


def test_unknown_manoeuvres_are_refused_listing_the_registry(hump, capsys):
    with pytest.raises(SystemExit) as e:
        main(["vehicle", "linear:2500", "--test", "slalom"])
    assert e.value.code == 2
    assert "invalid choice: 'slalom' (choose from 'bsst', 'dlc', 'road', 'hump')" in capsys.readouterr().err
    from dampnet.sweep import SpecError, parse_spec

    with pytest.raises(SpecError, match=r"fullcar.tests\[1\]: 'slalom' is not a full-vehicle test; "
                                        r"valid: bsst, dlc, road, hump"):
        parse_spec({"fullcar": {"tests": ["dlc", "slalom"]}})
    with pytest.raises(ValueError, match="'slalom' is not a full-vehicle test; valid: bsst, dlc, road, hump"):
        maneuvers.build("slalom", DT)
    with pytest.raises(ValueError, match="already registered"):
        maneuvers.register(hump["recipe"])
    with pytest.raises(ValueError, match="setting 'tilt' is not registered"):
        maneuvers.register(maneuvers.ManeuverRecipe("tilt", "", hump["build_hump"], hump["hump_metrics"], print,
                                                    {"tilt": 1.0}, (), (), "x"))


def test_the_bounce_sweep_settings_work_from_the_command_line(tmp_path, capsys):
    cli = vehicle_run(tmp_path, "b", "--test", "bsst", "--bsst-f0", "2", "--bsst-f1", "4", "--bsst-rate", "1",
                      "--bsst-amplitude", "0.002", "--mode", "pitch")
    meta = cli["maneuver"]
    assert (meta["f0_hz"], meta["f1_hz"], meta["amplitude_m"], meta["mode"]) == (2.0, 4.0, 0.002, "pitch")
    t = np.load(tmp_path / "b" / "run.npz")["t"]
    assert t[-1] == meta["pre_s"] + 1.0 + meta["post_s"]   # one octave at 1 octave/s (not 53 s: 0.5-20 Hz at 0.1)
    # the same as the sweep's cell builds it from the same settings (dampnet.sweep.fullcar_cell)
    from dampnet.sweep.fullcar_cell import maneuver

    man = maneuver({"test": "bsst", "dt": DT, "mode": "pitch", "bsst_amplitude_m": 0.002, **SHORT_BSST})
    api = maneuvers.run(load_spec("linear:2500"), man, "low")
    # a 2-4 Hz sweep has no wheel hop: its peak metrics are None (the same in both)
    assert {k for k, v in cli["metrics"].items() if v is None} == {k for k, v in api["metrics"].items() if v is None}
    assert {k: v for k, v in cli["metrics"].items() if v is not None} == pytest.approx(
        {k: v for k, v in api["metrics"].items() if v is not None}, rel=1e-12)
    assert main(["vehicle", "linear:2500", "--test", "bsst", "--bsst-f1", "0", "--out", str(tmp_path / "x")]) == 2
    assert "--bsst-f1: expected a finite number in [0.01, 100] Hz, got 0.0" in capsys.readouterr().err
    assert main(["vehicle", "linear:2500", "--test", "dlc", "--bsst-rate", "1", "--out", str(tmp_path / "x")]) == 2
    assert "--bsst-rate: dlc does not take it (it applies to bsst); drop --bsst-rate" in capsys.readouterr().err


def test_the_vehicle_damping_settings_are_control_laws(hump, tmp_path, monkeypatch, capsys):
    """`dampnet vehicle --damping`, the sweep's [fullcar] damping and the full-car study name laws
    of dampnet.recipes.control_laws (VEHICLE_DAMPING): a law and a setting registered here run
    through `dampnet vehicle`; each built-in one is its law, limited to the damper's levels."""
    from dampnet.recipes import control_laws
    from dampnet.sim.calibration import damping_levels
    from dampnet.sim.vehicle import Controller

    spec = load_spec("linear:2500")
    # the built-in settings: the registry's law, calibrated on the damper, with the levels as limits
    lv = damping_levels(load_spec("default"))
    for damping, law in control_laws.VEHICLE_DAMPING.items():
        ctrl = control_laws.vehicle_controller(load_spec("default"), damping)
        # calibrated on the full car's mean corner (the force-tracking laws' gains depend on it)
        made = control_laws.make(law, load_spec("default"), control_laws.corner_vehicle())
        assert ctrl.to_dict() == {**made.to_dict(),
                                  "u_min": min(lv.values()), "u_max": max(lv.values())}
    with pytest.raises(Exception, match="damping must be one of low, high, skyhook, skyhook_force, .*clipped_optimal, got 'mid'"):
        control_laws.vehicle_controller(spec, "mid")

    def mid(ctx):
        return Controller(kind="passive", u_passive=0.5 * (ctx.levels["low"] + ctx.levels["high"]))

    control_laws.register(control_laws.ControlLaw("passive_mid_test", "passive halfway between the levels", mid))
    monkeypatch.setitem(control_laws.VEHICLE_DAMPING, "mid", "passive_mid_test")
    try:
        res = vehicle_run(tmp_path, "mid", "--test", "hump", "--damping", "mid")
    finally:
        control_laws.unregister("passive_mid_test")
    lv = damping_levels(spec)
    assert res["damping"] == "mid"
    assert res["controller"]["u_passive"] == pytest.approx(0.5 * (lv["low"] + lv["high"]), abs=0)
    assert (res["controller"]["u_min"], res["controller"]["u_max"]) == (min(lv.values()), max(lv.values()))


def test_a_full_vehicle_law_is_calibrated_on_the_cars_corner(hump, monkeypatch):
    """A law offered to the full vehicle is calibrated by the registry on the damper and on the full
    car's mean corner (control_laws.corner_vehicle: m_s / 4, the axles' mean m_us and k_s, k_t), the
    car's fields given to the run included: groundhook_continuous's c_gnd = 2 zeta sqrt((k_s + k_t) m_us),
    zeta = 1/sqrt(2); the run records the law's name beside the runtime's kind. Cost: 0.1 s."""
    import math

    from dampnet.recipes import control_laws

    corner = control_laws.corner_vehicle()
    assert (corner.m_s, corner.m_us, corner.k_s, corner.k_t) == (650.0, 40.0, 15000.0, 200000.0)
    monkeypatch.setitem(control_laws.VEHICLE_DAMPING, "ground", "groundhook_continuous")
    spec = load_spec("default")
    car = {"m_us_f": 70.0, "m_us_r": 50.0, "k_s_f": 20000.0}
    ctrl = control_laws.vehicle_controller(spec, "ground", car)
    assert ctrl.c_gnd == pytest.approx(math.sqrt(2.0) * math.sqrt((17500.0 + 200000.0) * 60.0), rel=1e-12)
    res = maneuvers.run(spec, maneuvers.build("hump", DT), "ground", car)
    assert res["law"] == "groundhook_continuous" and res["controller"] == ctrl.to_dict()
    assert res["controller"]["kind"] == "groundhook_continuous"


@pytest.mark.parametrize("args, words", [
    (["--bsst-rate", "1e9"], "--bsst-rate: expected a finite number in [0.01, 10] octave/s, got 1000000000.0"),
    (["--bsst-rate", "1e-6"], "--bsst-rate: expected a finite number in [0.01, 10] octave/s, got 1e-06"),
    (["--bsst-amplitude", "1e-9"], "--bsst-amplitude: expected a finite number in [1e-06, 0.1] m, got 1e-09"),
    (["--bsst-f0", "1e-5"], "--bsst-f0: expected a finite number in [0.01, 100] Hz, got 1e-05"),
    (["--bsst-f0", "19.9999", "--bsst-f1", "20"],
     "--bsst-f1 20 Hz: expected at least a third of an octave above --bsst-f0 19.9999 Hz (>= 25.2 Hz)"),
    (["--bsst-f0", "0.5", "--bsst-f1", "0.63", "--bsst-rate", "10"],
     "--bsst-rate 10 octave/s: the sweep 0.5 -> 0.63 Hz holds 0.0188 cycles: expected at least 2"),
])
def test_a_bounce_sweep_with_nothing_to_measure_is_refused(tmp_path, capsys, args, words):
    """Issue 49, items 8/10: `vehicle --bsst-rate 1e9` ran (acc_rms 0.0), `--bsst-rate 1e-6` failed
    allocating 198 GiB (a traceback), `--bsst-f0 19.9999 --bsst-f1 20` ran with every peak None.
    Each setting has a range (dampnet.recipes.maneuvers.Setting.range) and the sweep's span and
    cycles are checked together (BSST_MIN_OCTAVES, BSST_MIN_CYCLES): one line naming the option,
    exit 2, before anything runs; the sweep's cells (maneuvers.build) refuse the same. Cost: 0.05 s each."""
    out = tmp_path / "x"
    assert main(["vehicle", "linear:2500", "--test", "bsst", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("dampnet: error: ") and words in err, err
    assert not out.exists()
    by_cli = {s.cli: s.name for s in maneuvers.SETTINGS.values()}
    given = {by_cli[a]: float(v) for a, v in zip(args[::2], args[1::2])}
    with pytest.raises(ValueError, match=words.split(":")[0]):
        maneuvers.build("bsst", DT, given)


def test_a_sweep_cell_with_nothing_to_measure_is_refused_when_the_spec_is_expanded():
    """Issue 49, items 8/10, in a sweep: a [fullcar] bsst cell of 19.9999 -> 20 Hz is a SpecError
    naming the cell's settings when the grid is expanded, not a failed cell at run time; each
    setting's range is the spec's own check. Cost: 0.05 s."""
    from dampnet.sweep import parse_spec
    from dampnet.sweep.grid import expand
    from dampnet.sweep.spec import SpecError

    spec = parse_spec({"fullcar": {"tests": ["bsst", "dlc"], "bsst_f0_hz": 19.9999, "bsst_f1_hz": 20.0}})
    with pytest.raises(SpecError, match=r"\[fullcar\] test bsst \(mode heave, bsst_amplitude_m 0.005, bsst_f0_hz "
                                        r"19.9999, bsst_f1_hz 20, bsst_rate_oct_s 0.1\): --bsst-f1 20 Hz: expected at "
                                        r"least a third of an octave above"):
        expand(spec)
    with pytest.raises(SpecError, match=r"bsst_rate_oct_s.*\[0.01, 10\] octave/s"):
        parse_spec({"fullcar": {"tests": "bsst", "bsst_rate_oct_s": 1e9}})
    assert len(expand(parse_spec({"fullcar": {"tests": ["bsst", "dlc"], **{k: v for k, v in SHORT_BSST.items()}}}))) == 2
