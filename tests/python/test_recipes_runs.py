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
import re
from pathlib import Path

import numpy as np
import pytest

from dampnet.cli import main
from dampnet.recipes import control_laws, roads
from dampnet.recipes import training as recipe

DOCS = Path(__file__).resolve().parents[2] / "docs" / "recipes.md"
#: the files of a model directory `dampnet train` writes
MODEL_FILES = {"model.json", "metrics.json", "model.h", "envelope.npz", "envelope.json"}
TINY = dict(decimate=50, max_epochs=15)


def recipe_block(section: str) -> str:
    """The first python code block under `## section` in docs/recipes.md."""
    text = DOCS.read_text(encoding="utf-8")
    part = text.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
    return re.search(r"```python\n(.*?)```", part, re.S).group(1)


@pytest.fixture
def kerb():
    """The docs' road recipe, run as written; the road removed after the test."""
    exec(compile(recipe_block("Roads"), str(DOCS), "exec"), {})
    yield roads.get("kerb")
    roads.unregister("kerb")


@pytest.fixture
def passive_mid():
    """The docs' control-law recipe, run as written; the law removed after the test."""
    exec(compile(recipe_block("Control laws"), str(DOCS), "exec"), {})
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
    assert meta["controller"]["kind"] == "passive"
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
    pytest.importorskip("dask.distributed")
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
    ("thesis-rough", "rough"), ("rough-road", "rough"), ("iso8608:C", "iso:C"), ("iso:c", "iso:C"),
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


def test_plan_tests_cases_are_registry_roads():
    from dampnet.planning import PlanError, _case_road

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
                 "--average", "2", "--workers", "1", "--decimate", "50", "--max-epochs", "15", "--quiet"]) == 0
    assert {p.name for p in (tmp_path / "cli").iterdir()} == MODEL_FILES
