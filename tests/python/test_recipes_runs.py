"""Issue 31, the vocabulary of runs: roads, control laws and the training request are each one
registry (dampnet.recipes) that the CLI, the sweep and the Python API read.

The recipes of docs/recipes.md are proved true here: the test runs the "Roads" and "Control
laws" code blocks themselves (a test-only road and law, registered from the test, no other file
edited) and runs both through `dampnet simulate` and a sweep (an in-process cluster, so the
registrations are the workers' too). A sweep cell trains with restarts and average and saves the
model directory `dampnet train` saves (with the envelope), as does `dampnet.train`; `dampnet
simulate default` runs the embedded model; old spellings still work; unknown names are refused
with the registry's names. Tiny work: a 6 m road, the rig's quick plan decimated by 50, 15 epochs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.recipes import control_laws, roads
from dampnet.recipes import training as recipe
from recipe_tree import run_doc_block

#: the files of a model directory `dampnet train` writes
MODEL_FILES = {"model.json", "metrics.json", "model.h", "envelope.npz", "envelope.json"}
TINY = dict(decimate=50, max_epochs=15)


@pytest.fixture
def kerb():
    """The docs' road recipe, run as written; the road removed after the test."""
    run_doc_block("Roads")
    yield roads.get("kerb")
    roads.unregister("kerb")


@pytest.fixture
def passive_mid():
    """The docs' control-law recipe, run as written; the law removed after the test."""
    run_doc_block("Control laws")
    yield control_laws.get("passive_mid")
    control_laws.unregister("passive_mid")


def _one_line_error(capsys, argv) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    return err


def _direct(model: str, road_text: str, law: str, speed: float = 10.0) -> dict:
    """The run's metrics computed here from the registries' objects (not through a front end)."""
    from dampnet.sim.dampers import load_spec
    from dampnet.sim.quarter_car.runs import simulate
    from dampnet.sim.vehicle import Vehicle

    spec, veh = load_spec(model), Vehicle()
    road = roads.build(road_text)
    return simulate(spec, road, speed if road.kind == "spatial" else None,
                    control_laws.make(law, spec, veh), veh)


# -- a test-only road and law through the CLI and a sweep ---------------------------------------

def test_the_recipes_road_and_law_run_through_the_cli(kerb, passive_mid, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["simulate", "truth", "--road", "kerb:height_m=0.05", "--control", "passive_mid",
                 "--out", str(out)]) == 0
    meta = json.loads((out / "metrics.json").read_text())
    assert meta["road"]["input"] == "kerb" and meta["road"]["height_m"] == 0.05   # the name's parameter
    assert meta["road"]["total_m"] == 6.0                                        # the default
    from dampnet.sim.calibration import damping_levels
    from dampnet.sim.dampers import truth_spec

    lv = damping_levels(truth_spec())
    assert meta["controller"]["kind"] == "passive" and meta["law"] == "passive_mid"   # the law's name, and its kind
    assert meta["controller"]["u_passive"] == pytest.approx(0.5 * (lv["low"] + lv["high"]))
    assert meta["metrics"] == _direct("truth", "kerb:height_m=0.05", "passive_mid")["metrics"]
    # the alias, and the registry in the help texts
    assert main(["simulate", "truth", "--road", "curb", "--control", "passive_mid", "--out", str(out), "--force"]) == 0
    assert json.loads((out / "metrics.json").read_text())["road"]["height_m"] == 0.1
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    assert "kerb" in help_text and "passive_mid" in help_text and "passive_low" in help_text


@pytest.fixture(scope="module")
def client():
    """An in-process cluster: the test's registrations are its worker's."""
    import needs

    needs.need_module("dask.distributed")
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster, \
            Client(cluster) as c:
        yield c


def test_the_recipes_road_and_law_run_through_a_sweep(kerb, passive_mid, client, tmp_path):
    from dampnet.sweep import run

    spec = {"simulation": {"models": ["truth"], "roads": ["kerb", "curb:height_m=0.05"], "speeds": [10.0],
                           "controllers": ["passive_mid", "passive_high"]}}
    df = run(spec, client=client, out=tmp_path / "sim", progress=False)
    assert len(df) == 4 and (df["status"] == "ok").all(), df[["status", "error"]]
    for _, row in df.iterrows():
        want = _direct("truth", row["road"], row["controller"])["metrics"]
        for k in ("acc_rms_m_s2", "acc_wk_rms_m_s2", "travel_max_m", "tyre_load_rms_n"):
            assert row[k] == want[k], (row["road"], row["controller"], k)
    # the kerb is a distance profile: the speed applies; it takes no seed or length: those are empty
    assert (df["speed"] == 10.0).all() and df["road_seed"].isna().all() and df["road_length_m"].isna().all()
    # each cell's record names its law beside the runtime's kind
    recs = [json.loads(f.read_text()) for f in (tmp_path / "sim" / "cells").glob("*.json")]
    assert sorted(r["law"] for r in recs) == ["passive_high", "passive_high", "passive_mid", "passive_mid"]
    assert all(r["controller_settings"]["kind"] == "passive" for r in recs)


#: a short bounce sweep of the full vehicle (2 -> 4 Hz at 1 octave/s, 2 ms steps)
SHORT_BSST = {"bsst_f0_hz": 2.0, "bsst_f1_hz": 4.0, "bsst_rate_oct_s": 1.0, "dt": 2e-3}


def test_the_recipes_law_runs_in_the_full_vehicle(passive_mid, client, tmp_path, monkeypatch):
    """The docs' law, offered to the full vehicle as the docs say (VEHICLE_DAMPING["mid"] =
    "passive_mid"), runs through `dampnet vehicle --damping mid` and a [fullcar] sweep: every corner at
    the mean of the damper's levels, the law's name recorded beside the runtime's kind, the CLI's and
    the sweep's metrics those of the registry's own run. Cost: 5 s."""
    from dampnet.recipes import maneuvers
    from dampnet.sim.calibration import damping_levels
    from dampnet.sim.dampers import load_spec
    from dampnet.sweep import run

    monkeypatch.setitem(control_laws.VEHICLE_DAMPING, "mid", "passive_mid")   # the docs' line, undone after
    spec = load_spec("default")
    lv = damping_levels(spec)
    man = maneuvers.build("bsst", SHORT_BSST["dt"], {k: v for k, v in SHORT_BSST.items() if k != "dt"})
    want = maneuvers.run(spec, man, "mid")
    assert want["controller"]["u_passive"] == pytest.approx(0.5 * (lv["low"] + lv["high"]), abs=0)
    assert want["law"] == "passive_mid" and want["controller"]["kind"] == "passive"
    assert want["metrics"]["acc_rms_m_s2"] != maneuvers.run(spec, man, "high")["metrics"]["acc_rms_m_s2"]
    out = tmp_path / "vehicle"
    assert main(["vehicle", "default", "--test", "bsst", "--damping", "mid", "--bsst-f0", "2", "--bsst-f1", "4",
                 "--bsst-rate", "1", "--dt", "0.002", "--out", str(out)]) == 0
    meta = json.loads((out / "metrics.json").read_text())
    assert meta["law"] == "passive_mid" and meta["damping"] == "mid" and meta["controller"] == want["controller"]
    assert meta["metrics"]["acc_rms_m_s2"] == want["metrics"]["acc_rms_m_s2"]
    df = run({"fullcar": {"models": ["default"], "tests": ["bsst"], "damping": ["mid"], **SHORT_BSST}},
             client=client, out=tmp_path / "fc", progress=False)
    assert len(df) == 1 and (df["status"] == "ok").all(), df[["status", "error"]]
    assert df["acc_rms_m_s2"].iloc[0] == want["metrics"]["acc_rms_m_s2"]
    rec = json.loads(next((tmp_path / "fc" / "cells").glob("*.json")).read_text())
    assert rec["law"] == "passive_mid" and rec["controller_settings"] == want["controller"]


# -- issue 52: the recipe's road in the full car; the parameters front ends fill ------------------

def test_the_recipes_road_runs_in_the_full_car_a_corner_replay_and_plan_tests(kerb, client, tmp_path, capsys):
    """Issue 52: `dampnet vehicle --test road` took only 'thesis' and ISO classes, `rig --replay
    --corner` translated by hand. The road added as docs/recipes.md says runs there too, and in a
    [fullcar] sweep and plan-tests: the front wheels drive the kerb at the speed (36 km/h: 10 m/s),
    both tracks the same profile (not random: it fills no seed), the rear a wheelbase (3.25 m)
    later, starting on its first elevation (not periodic). Cost: 5 s."""
    from dampnet.modeldir import default_model_path
    from dampnet.campaign.replay import corner_drive
    from dampnet.sweep import run

    out = tmp_path / "v"
    assert main(["vehicle", "linear:1500", "--test", "road", "--road", "kerb:height_m=0.05", "--speed", "36",
                 "--out", str(out)]) == 0
    meta = json.loads((out / "metrics.json").read_text())
    assert meta["maneuver"]["input"] == "kerb" and meta["maneuver"]["height_m"] == 0.05
    road = np.load(out / "run.npz")["road"]
    k = roads.build("kerb:height_m=0.05")
    x = 10.0 * (np.arange(road.shape[0]) * 1e-3)
    assert road.shape[0] == 601                                           # 6 m at 10 m/s, 1 ms steps
    np.testing.assert_allclose(road[:, 0], np.interp(x, k.x, k.z), rtol=0, atol=1e-15)   # front left
    np.testing.assert_array_equal(road[:, 1], road[:, 0])                              # right = left
    np.testing.assert_allclose(road[:, 2], np.interp(x - 3.25, k.x, k.z), rtol=0, atol=1e-15)   # rear
    assert road[:, 0].max() == pytest.approx(0.05) and road[:325, 2].max() == 0.0 and road[:, 2].max() > 0.0
    assert meta["metrics"]["acc_rms_m_s2"] > 0.0
    # a [fullcar] sweep cell of the same road is the same run; it takes no seed: road_seed is empty
    df = run({"fullcar": {"models": ["linear:1500"], "tests": ["road"], "roads": ["kerb:height_m=0.05"],
                          "speeds_kmh": 36.0, "road_seeds": [0, 1]}}, client=client, out=tmp_path / "s", progress=False)
    assert len(df) == 1 and (df["status"] == "ok").all(), df[["status", "error"]]
    assert df["road_seed"].isna().all() and df["acc_rms_m_s2"].iloc[0] == meta["metrics"]["acc_rms_m_s2"]
    # a full-car corner replayed on the rig: the rear left climbs the kerb within the replayed second
    d = corner_drive("kerb", speed_m_s=5.0, law="low", corner="rl", duration_s=0.5)
    assert d.meta["road_text"] == "kerb" and d.meta["corner"] == "rl" and np.ptp(d.x) > 1e-3
    assert main(["rig", str(tmp_path / "r"), "--replay", "kerb", "--corner", "fl", "--speed", "5", "--duration",
                 "0.5", "--control", "low", "--no-progress"]) == 0
    # plan-tests' built-in case
    assert main(["plan-tests", str(default_model_path()), "kerb:low", "--budget", "2",
                 "--out", str(tmp_path / "plan.json")]) == 0


def test_a_random_full_car_road_keeps_its_parameters_and_correlated_tracks():
    """Issue 52: a parameter written in the road's text reaches the full car (a corner replay once
    refused rough:rms_m, the translation dropping it): half the RMS is half the road, and a seed
    in the text wins over --seed, the right track mixing in the road at the next seed. Cost: 0.05 s."""
    from dampnet.recipes import maneuvers
    from dampnet.sim.full_car.maneuvers import TRACK_COHERENCE
    from dampnet.sim.roads import thesis_rough_road

    full = maneuvers.build("road", 1e-3, {"road": "rough", "road_seed": 4})
    half = maneuvers.build("road", 1e-3, {"road": "rough:rms_m=0.008", "road_seed": 4})
    np.testing.assert_allclose(half.road, 0.5 * full.road, rtol=1e-12, atol=1e-18)
    named = maneuvers.build("road", 1e-3, {"road": "rough:seed=4", "road_seed": 9})
    assert np.array_equal(named.road, full.road)
    a, b = thesis_rough_road(seed=4), thesis_rough_road(seed=5)
    right = TRACK_COHERENCE * a.z + np.sqrt(1 - TRACK_COHERENCE ** 2) * b.z
    x = 60.0 / 3.6 * (np.arange(full.road.shape[0]) * 1e-3)
    np.testing.assert_array_equal(full.road[:, 1], np.interp(x, a.x, right))


@pytest.mark.parametrize("name", ["seed", "length_m", "speed_m_s"])
def test_a_road_parameter_named_like_a_filled_one_is_refused_at_registration(name):
    """Issue 52: the sweep filled any road parameter named length_m or seed from its own settings;
    a road whose width was called length_m failed every sweep cell. Such a road is refused when it
    is registered, naming the parameter; nothing is registered. Cost: 0.01 s."""
    with pytest.raises(roads.RoadError, match=rf"road 'ramp': parameter '{name}' is a name the front ends fill "
                                              r"\(seed, length_m, speed_m_s\)"):
        roads.register(roads.RoadKind("ramp", "a ramp", "spatial", lambda p: None,
                                      (roads.RoadParam(name, "m", 1.0, "ramp width"),)))
    assert not roads.is_named("ramp")
    with pytest.raises(roads.RoadError, match="road 'ramp': fills 'width_m': a front end fills only seed, "
                                              "length_m, speed_m_s"):
        roads.RoadKind("ramp", "a ramp", "spatial", lambda p: None, fills=("width_m",))


def test_a_road_takes_only_the_filled_parameters_it_declares():
    """A road declaring fills=("length_m", "speed_m_s") gets the front end's values (the name's
    win), one declaring none keeps its defaults whatever the context; a context key that is not a
    filled name is a programming error. Cost: 0.01 s."""
    seen = []
    ramp = roads.register(roads.RoadKind(
        "ramp", "a ramp", "spatial", lambda p: seen.append(dict(p)) or roads.build("bump"),
        (roads.RoadParam("width_m", "m", 2.0, "ramp width", float, 0.1, 10.0),), fills=("length_m", "speed_m_s")))
    try:
        assert ramp.param_names() == ("width_m", "length_m", "speed_m_s")
        roads.build("ramp", seed=3, length_m=50.0, speed_m_s=12.0)
        roads.build("ramp:length_m=40,width_m=1", length_m=50.0)
        assert seen == [{"width_m": 2.0, "length_m": 50.0, "speed_m_s": 12.0},
                        {"width_m": 1.0, "length_m": 40.0, "speed_m_s": 20.0}]
        with pytest.raises(roads.RoadError, match=r"road 'ramp': speed_m_s: expected 0.001 to 100 \[m/s\], got 0.0"):
            roads.build("ramp", speed_m_s=0.0)
        with pytest.raises(TypeError, match="road context 'width_m'"):
            roads.build("ramp", width_m=3.0)
        assert roads.parse("bump").params(seed=5, length_m=9.0) == {"height_m": 0.05, "width_m": 0.5}
    finally:
        roads.unregister("ramp")


def test_a_sweep_parses_each_road_text_once(kerb, monkeypatch):
    """Issue 52: the sweep parsed a road's text for every cell (checking, dropping what does not
    apply, building). Expanding and building a sweep of 3 roads x 3 seeds x 2 speeds and a
    [fullcar] one of 2 roads x 2 seeds parses each text once. Cost: 0.05 s."""
    from dampnet.sweep import fullcar_cell, sim_cell
    from dampnet.sweep.grid import expand
    from dampnet.sweep.inputs import bind
    from dampnet.sweep.spec import parse_spec

    calls = []
    real = roads.get
    monkeypatch.setattr(roads, "get", lambda name: calls.append(name) or real(name))
    texts = ["kerb", "iso:C", "rough"]
    roads._parse.cache_clear()
    spec = parse_spec({"simulation": {"models": ["linear:1500"], "roads": texts, "road_seeds": [0, 1, 2],
                                      "speeds": [10.0, 20.0]},
                       "fullcar": {"models": ["linear:1500"], "tests": ["road"], "roads": ["kerb", "iso:B"],
                                   "road_seeds": [0, 1]}})
    cells = expand(spec)
    bind(cells, spec)
    for c in cells:
        if c.kind == "simulation":
            sim_cell.road(c.params, c.inputs["road"])
        else:
            fullcar_cell.maneuver(c.params)
    assert len(cells) == 1 * 2 + 3 * 2 * 2 + 1 + 2       # kerb: no seeds; iso:C, rough: 3 seeds; fullcar
    assert sorted(calls) == ["iso", "iso", "kerb", "rough"]   # iso:C, iso:B, kerb, rough: once each


def test_old_profile_spellings_of_the_full_car(tmp_path, capsys):
    """`vehicle --profile thesis|A..H` is the old spelling of --road rough|iso:CLASS (same road);
    the sweep's old [fullcar] profiles key is refused naming roads. Cost: 0.05 s."""
    from dampnet.commands.vehicle import _old_profile
    from dampnet.recipes import maneuvers
    from dampnet.sweep.spec import SpecError, parse_spec

    assert _old_profile("thesis") == "thesis" and _old_profile("c") == "iso:C"
    for old, new in (("thesis", "rough"), ("C", "iso:C")):
        a = maneuvers.build("road", 1e-3, {"road": _old_profile(old)})
        assert np.array_equal(a.road, maneuvers.build("road", 1e-3, {"road": new}).road)
    with pytest.raises(ValueError, match=r"--profile 'Z': expected thesis or an ISO 8608 class A..H \(--profile is "
                                         "the old spelling of --road ROAD"):
        _old_profile("Z")
    with pytest.raises(SpecError, match=r"fullcar.profiles.*renamed roads"):
        parse_spec({"fullcar": {"tests": ["road"], "profiles": ["C"]}})


# -- unknown names, old spellings ---------------------------------------------------------------

def test_unknown_names_are_refused_listing_the_registries(kerb, passive_mid, tmp_path, capsys):
    from dampnet.sweep.spec import SpecError, parse_spec

    err = _one_line_error(capsys, ["simulate", "truth", "--road", "cobbles", "--out", str(tmp_path / "a")])
    assert "unknown road 'cobbles'" in err and all(n in err for n in roads.names()) and "kerb" in err
    err = _one_line_error(capsys, ["simulate", "truth", "--road", "bump:depth=3", "--out", str(tmp_path / "a")])
    assert "unknown parameter 'depth'" in err and "height_m [m]" in err
    err = _one_line_error(capsys, ["simulate", "truth", "--road", "bump", "--control", "soft", "--out",
                                   str(tmp_path / "a")])
    assert "--control: 'soft' is not a control law" in err and all(f"'{n}'" in err for n in control_laws.names())
    assert "'passive_mid'" in err and "'passive_low'" in err
    with pytest.raises(SpecError, match=r"simulation.roads\[0\].*not a road: use .*kerb"):
        parse_spec({"simulation": {"roads": ["cobbles"]}})
    with pytest.raises(SpecError, match=r"simulation.controllers.*'soft' is not a controller; valid: .*passive_mid"):
        parse_spec({"simulation": {"roads": ["kerb"], "controllers": "soft"}})
    with pytest.raises(roads.RoadError, match="unknown road"):
        roads.get("cobbles")


@pytest.mark.parametrize("old, new", [
    ("sine_sweep", "sweep"), ("sine-sweep", "sweep"), ("SWEEP", "sweep"), ("thesis_rough", "rough"),
    ("thesis-rough", "rough"), ("rough-road", "rough"), ("thesis", "rough"), ("iso8608:C", "iso:C"), ("iso:c", "iso:C"),
    ("iso:E", "iso:class=E"), ("iso:C", "iso")])
def test_old_road_spellings_build_the_same_road(old, new):
    a, b = roads.build(old, seed=3), roads.build(new, seed=3)
    assert a.name == b.name and a.kind == b.kind and np.array_equal(a.z, b.z) and np.array_equal(a.x, b.x)


def test_the_registry_builds_the_profiles_with_their_defaults():
    from dampnet.sim.roads import bump, impulse, iso8608, sine_sweep, thesis_rough_road

    for text, want in (("impulse", impulse()), ("bump", bump()), ("sweep", sine_sweep()),
                       ("rough", thesis_rough_road(seed=2)), ("iso:A", iso8608("A", seed=2))):
        got = roads.build(text, seed=2)
        assert np.array_equal(got.z, want.z) and got.meta == want.meta, text
    assert roads.build("iso:B", seed=1, length_m=50.0).length == iso8608("B", length_m=50.0, seed=1).length
    assert roads.build("iso:B,length_m=40", length_m=50.0).length == 40.0      # the name's value wins


def test_old_control_spellings_still_work(tmp_path):
    """--control passive --damping low is passive_low; the sweep's names are the CLI's now."""
    from dampnet.sim.dampers import truth_spec
    from dampnet.sim.vehicle import Vehicle

    spec, veh = truth_spec(), Vehicle()
    assert control_laws.make("passive", spec, veh, damping="low") == control_laws.make("passive_low", spec, veh)
    assert control_laws.make("passive", spec, veh) == control_laws.make("passive_high", spec, veh)
    assert control_laws.make("passive", spec, veh, u=1.5).u_passive == 1.5
    for out, law in ((tmp_path / "a", ["--control", "passive", "--damping", "low"]),
                     (tmp_path / "b", ["--control", "passive_low"])):
        assert main(["simulate", "truth", "--road", "impulse", *law, "--out", str(out)]) == 0
    a, b = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in "ab")
    assert a["metrics"] == b["metrics"] and a["controller"] == b["controller"]
    assert (a["law"], b["law"]) == ("passive", "passive_low")     # each run names the law it was asked for


def test_plan_tests_cases_are_registry_roads():
    from dampnet.campaign.planning import PlanError, _case_road

    req, level = _case_road("rough-road:low")
    assert req.kind.name == "rough" and level == "low" and req.kind.case_speeds_m_s == (10.0, 20.0)
    req, level = _case_road("iso:C:high")
    assert req.kind.name == "iso" and req.params()["class"] == "C" and level == "high"
    assert _case_road("sine-sweep")[0].profile == "temporal"
    assert _case_road("no-such-dir") is None
    with pytest.raises(PlanError, match="class: expected ISO 8608 class"):
        _case_road("iso:Z")
    with pytest.raises(PlanError, match=r"damping 'medium': expected iso:C:low or iso:C:high"):
        _case_road("iso:C:medium")


# -- the default model --------------------------------------------------------------------------

def test_simulate_default_runs_the_embedded_model(tmp_path):
    from dampnet.modeldir import default_model_path

    assert main(["simulate", "default", "--road", "impulse", "--out", str(tmp_path / "d")]) == 0
    assert main(["simulate", str(default_model_path()), "--road", "impulse", "--out", str(tmp_path / "p")]) == 0
    d, p = (json.loads((tmp_path / x / "metrics.json").read_text()) for x in "dp")
    assert d["metrics"] == p["metrics"] and d["damper"] == p["damper"] and "coverage" in d   # a neural model


# -- the training request -----------------------------------------------------------------------

def test_every_request_field_is_spelled_where_the_table_says():
    """The options table's rows are the request's fields; each CLI option a row names is `dampnet
    train`'s, each sweep key the sweep's [training] key, both with the row's help first."""
    import argparse

    from dampnet.commands import train
    from dampnet.sweep.spec import training_params
    from dampnet.training.settings import OPTIONS

    names = set(recipe.TrainingRequest()._values)
    assert names == {n for n, row in OPTIONS.items() if row.request}
    parser = train.add_parser(argparse.ArgumentParser().add_subparsers())
    options = {o for a in parser._actions for o in a.option_strings}
    sweep_keys = {p.key: p for p in training_params()}
    helps = {o: a.help for a in parser._actions for o in a.option_strings}
    for f in OPTIONS.values():
        assert f.cli is None or f.cli in options, f.name
        assert f.sweep is None or f.sweep in sweep_keys, f.name
        # the option's help says what the row says first (then only how the command line spells it)
        assert f.cli is None or helps[f.cli].startswith(f.help()), (f.name, helps[f.cli])
        assert f.sweep is None or sweep_keys[f.sweep].help.startswith(f.help()), f.name


def test_sweep_specs_take_restarts_and_average():
    from dampnet.sweep.spec import SpecError, parse_spec

    s = parse_spec({"training": {"datasets": "rig:quick", "restarts": 6, "average": [1, 2]}})
    assert s.sections["training"].axes["restarts"] == [6] and s.sections["training"].axes["average"] == [1, 2]
    assert parse_spec({"training": {"datasets": "rig:quick", "restarts": "auto"}}).sections["training"].axes[
        "restarts"] == ["auto"]
    with pytest.raises(SpecError, match=r"training.average: average \(--average\): 3 restarts averaged, but only 2"):
        parse_spec({"training": {"datasets": "rig:quick", "restarts": 2, "average": 3}})
    with pytest.raises(SpecError, match=r"training.restarts: restarts \(--restarts"):
        parse_spec({"training": {"datasets": "rig:quick", "restarts": 0}})


@pytest.fixture(scope="module")
def quick():
    from dampnet.rig import generate

    return generate("quick", seed=0)


def test_python_train_returns_the_model_with_its_envelope(quick, tmp_path):
    import dampnet
    from dampnet.envelope import check_belongs
    from dampnet.sim.dampers import load_spec

    trained = dampnet.train(quick, seed=1, **TINY)
    model, info, split = trained                               # as dampnet.train always unpacked
    assert model is trained.model and trained.envelope is not None
    check_belongs(trained.envelope, model)
    trained.save(tmp_path / "m")
    assert {p.name for p in (tmp_path / "m").iterdir()} == MODEL_FILES
    spec = load_spec(str(tmp_path / "m"))
    assert spec.meta["envelope"] is not None                   # its runs report coverage, not "no joint envelope"
    assert json.loads((tmp_path / "m" / "metrics.json").read_text())["holdout"]["overall"]["nrmse"] > 0


def test_a_sweep_cell_trains_with_restarts_and_average_as_dampnet_train(quick, client, tmp_path):
    import dampnet
    from dampnet.model import MlpModel
    from dampnet.sweep import run

    spec = {"training": {"datasets": ["rig:quick"], "restarts": 2, "average": 2, "seeds": [1], **TINY}}
    df = run(spec, client=client, out=tmp_path / "sw", progress=False)
    assert len(df) == 1 and (df["status"] == "ok").all(), df[["status", "error"]]
    assert df["restart_score"][0] == "combined"
    cell_dir = tmp_path / "sw" / df["model_dir"][0]
    assert {p.name for p in cell_dir.iterdir()} == MODEL_FILES
    cell_model = MlpModel.load(cell_dir / "model.json")
    assert cell_model.meta["restarts"]["n"] == 2 and cell_model.hidden == (60,)   # 2 x 30 averaged
    # the same request through the Python API: the same model
    mine = dampnet.train(quick, seed=1, restarts=2, average=2, workers=1, **TINY)
    assert mine.model.model_id() == cell_model.model_id()
    # and through the CLI, on the same data written by the rig: the same files
    data = tmp_path / "quick"
    assert main(["rig", str(data), "--plan", "quick", "--seed", "0", "--no-progress"]) == 0
    assert main(["train", str(data), "--out", str(tmp_path / "cli"), "--seed", "1", "--restarts", "2",
                 "--average", "2", "--workers", "1", "--decimate", "50", "--max-epochs", "15", "--quiet",
                 "--valve", "off"]) == 0
    assert {p.name for p in (tmp_path / "cli").iterdir()} == MODEL_FILES


# -- every law calibrated by the registry (issue 52, item 3) --------------------------------------

def test_groundhook_continuous_is_calibrated_as_skyhook_continuous(tmp_path):
    """groundhook_continuous is calibrated on the damper and the car by the registry, by skyhook's
    principle (c_gnd = 2 zeta sqrt((k_s + k_t) m_us), zeta = 1/sqrt(2): 4147 N s/m for Table 5, not the
    runtime's default 2500; c_min / c_max the damper's equivalent damping at its levels, as skyhook's),
    and `simulate` and the quarter-car FMU's --controller get those gains from it, naming the law
    (external, the FMU's own u input, stays the runtime's). Cost: 2 s."""
    import argparse
    import math

    from dampnet.export.fmu.quarter_car import quarter_car_description
    from dampnet.modeldir import default_model
    from dampnet.recipes.export_targets import _fmu_start_values
    from dampnet.sim.dampers import neural_spec, truth_spec
    from dampnet.sim.vehicle import Controller, Vehicle

    truth, veh = truth_spec(), Vehicle()
    sky = control_laws.make("skyhook_continuous", truth, veh)
    gnd = control_laws.make("groundhook_continuous", truth, veh)
    assert gnd.kind == "groundhook_continuous"
    assert gnd.c_gnd == pytest.approx(2.0 / math.sqrt(2.0) * math.sqrt((15000.0 + 200000.0) * 40.0), rel=1e-12)
    assert round(gnd.c_gnd) == 4147 and gnd.c_gnd != Controller.c_gnd
    assert (gnd.c_min, gnd.c_max) == (sky.c_min, sky.c_max) and 1000.0 < gnd.c_min < 2500.0 < 4000.0 < gnd.c_max
    assert (gnd.u_soft, gnd.u_hard, gnd.u_tau_s) == (sky.u_soft, sky.u_hard, sky.u_tau_s) == (5.0, 0.0, 0.005)
    # calibrated on the car: twice the unsprung mass, sqrt(2) times the gain
    assert control_laws.make("groundhook_continuous", truth, Vehicle(m_us=80.0)).c_gnd == \
        pytest.approx(math.sqrt(2.0) * gnd.c_gnd, rel=1e-12)
    # `dampnet simulate --control groundhook_continuous`: the registry's gains, the law's name recorded
    out = tmp_path / "run"
    assert main(["simulate", "default", "--road", "bump", "--control", "groundhook_continuous", "--out", str(out)]) == 0
    meta = json.loads((out / "metrics.json").read_text())
    model = default_model()
    want = control_laws.make("groundhook_continuous", neural_spec(model), veh)
    assert meta["law"] == "groundhook_continuous" and meta["controller"] == want.to_dict()
    # the quarter-car FMU: --controller LAW is the registry's law calibrated on the model, --set over it
    args = argparse.Namespace(controller="groundhook_continuous", set=["m_us=80", "c_min=600"])
    vehicle, controller, law = _fmu_start_values(args, model)
    assert law == "groundhook_continuous" and vehicle == {"m_us": 80.0}
    assert controller == {**control_laws.make(law, neural_spec(model), Vehicle(m_us=80.0)).to_dict(), "c_min": 600.0}
    text = quarter_car_description(model, vehicle, controller, law=law).description
    assert "controller groundhook_continuous (control law groundhook_continuous, calibrated on this damper)" in text
    assert _fmu_start_values(argparse.Namespace(controller="external", set=["u_tau_s=0.01"]), model) == \
        ({}, {"kind": "external", "u_tau_s": 0.01}, None)
    bad = argparse.Namespace(controller="soft", set=[])
    with pytest.raises(ValueError, match="--controller: 'soft' is not a control law; valid: 'passive'"):
        _fmu_start_values(bad, model)


def test_a_csv_road_runs_in_the_full_car_and_in_a_fullcar_sweep(tmp_path, capsys, client):
    """Issue 52, item 2: `dampnet vehicle --test road --road FILE.csv` refused the CSV profile its own
    error named ("or a CSV file"). Now the profile drives both tracks at the speed, the rear a
    wheelbase later; a missing file is one line naming it. A [fullcar] sweep takes the CSV too: the
    road is a cell input, its content in the cell's key (a changed file is a new cell, never taken
    as done on --resume), its cell equal to the CLI's run. Cost: 4 s."""
    from dampnet.sweep import parse_spec, run
    x = np.arange(0.0, 30.0, 0.05)
    z = np.where((x > 5.0) & (x < 5.5), 0.03, 0.0)
    (tmp_path / "step.csv").write_text("distance_m,elevation_m\n" + "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(x, z)))
    out = tmp_path / "v"
    assert main(["vehicle", "linear:1500", "--test", "road", "--road", str(tmp_path / "step.csv"), "--speed", "36",
                 "--out", str(out)]) == 0
    road = np.load(out / "run.npz")["road"]
    t = np.arange(road.shape[0]) * 1e-3
    np.testing.assert_allclose(road[:, 0], np.interp(10.0 * t, x, z), rtol=0, atol=1e-15)          # front left
    np.testing.assert_array_equal(road[:, 1], road[:, 0])                                           # right = left
    np.testing.assert_allclose(road[:, 2], np.interp(10.0 * t - 3.25, x, z), rtol=0, atol=1e-15)   # rear
    assert road.shape[0] == 2996 and road[:, 0].max() == 0.03    # 29.95 m at 10 m/s: 2995 steps of 1 ms, t = 0 too
    assert json.loads((out / "metrics.json").read_text())["metrics"]["acc_rms_m_s2"] > 0.0
    capsys.readouterr()
    assert main(["vehicle", "linear:1500", "--test", "road", "--road", str(tmp_path / "nope.csv"),
                 "--out", str(tmp_path / "w")]) == 2
    assert "nope.csv: file not found" in capsys.readouterr().err and not (tmp_path / "w").exists()
    cli = json.loads((out / "metrics.json").read_text())["metrics"]
    # the sweep: a relative path (to the spec's folder), a seed axis the CSV does not take, and rough
    spec = {"fullcar": {"models": ["linear:1500"], "tests": ["road"], "roads": ["step.csv", "rough"],
                        "road_seeds": [0, 1], "speeds_kmh": [36.0], "dt": 1e-3}}
    sp = parse_spec(spec, base=tmp_path)
    df = run(sp, client=client, out=tmp_path / "s", progress=False)
    assert (df["status"] == "ok").all(), df[["status", "error"]]
    csv_rows = df[df["road"] == "step.csv"]
    assert len(csv_rows) == 1 and csv_rows["road_seed"].isna().all()      # one cell: no seed to vary
    assert len(df[df["road"] == "rough"]) == 2
    assert csv_rows["acc_rms_m_s2"].iloc[0] == pytest.approx(cli["acc_rms_m_s2"], rel=1e-12)
    # the file's content is in the key: edited, its cell is new on --resume
    (tmp_path / "step.csv").write_text((tmp_path / "step.csv").read_text().replace(",0.03", ",0.06"))
    again = run(parse_spec(spec, base=tmp_path), client=client, out=tmp_path / "s", resume=True, progress=False)
    assert main(["vehicle", "linear:1500", "--test", "road", "--road", str(tmp_path / "step.csv"), "--speed", "36",
                 "--out", str(tmp_path / "v2")]) == 0
    edited = json.loads((tmp_path / "v2" / "metrics.json").read_text())["metrics"]["acc_rms_m_s2"]
    higher = again[again["road"] == "step.csv"]["acc_rms_m_s2"].iloc[0]
    assert higher == pytest.approx(edited, rel=1e-12) and higher > 1.5 * cli["acc_rms_m_s2"]
