"""docs/recipes.md's road, control-law, manoeuvre, export-target and training-option recipes applied
as the built-ins the doc says they become (issue 52 item 5): each recipe's code block, read from the
doc, appended to the end of its registry module (recipes/roads.py, control_laws.py, maneuvers.py,
export_targets.py, training/settings.py) in a copy of the tree (tests/python/recipe_tree.py), no other file edited. In
the copy, with this tree's built dampnet._core: its CLI lists each new entry and runs it (the
manoeuvre also in a sweep, whose worker processes import the registry module, not a test), and
the copy's registry-wide tests pass (every road builds, the plan-tests cases are registry roads,
the simulation's names, the full-car sweeps, `--help` still light), with no test registering
anything.

test_recipes_runs.py, test_recipes_maneuvers.py and test_recipes_export.py run the same blocks
registered from a test (the path of a user's own module) through every front end, as
test_training_options.py does the training option's; the stateful feature's (C++) recipe is
test_state_recipe.py's. Cost: about 40 s warm (the copy, seven CLI runs, a one-worker sweep, two
pytest runs in the copy).
"""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sysconfig
from pathlib import Path

import pytest

import recipe_tree
from cbuild import ROOT

#: each registry module (under python/dampnet) and the docs/recipes.md section appended to it
BUILT_INS = (("recipes/roads.py", "Roads"), ("recipes/control_laws.py", "Control laws"),
             ("recipes/maneuvers.py", "Manoeuvres"), ("recipes/export_targets.py", "Export targets"),
             ("training/settings.py", "Training requests"))


@pytest.fixture(scope="module")
def copy_env(tmp_path_factory) -> recipe_tree.CopyEnv:
    from dampnet import _core

    root = tmp_path_factory.mktemp("recipes-in-tree")
    tree = recipe_tree.copy_tree(root / "tree")
    pkg = tree / "python" / "dampnet"
    for module, section in BUILT_INS:
        path = pkg / module
        path.write_text(path.read_text() + f"\n\n# {section}: the recipe of docs/recipes.md, as a built-in\n"
                        + recipe_tree.doc_block(section))
    shutil.copy2(_core.__file__, pkg / Path(_core.__file__).name)   # this tree's runtime: no C++ edited
    assert Path(_core.__file__).name.endswith(sysconfig.get_config_var("EXT_SUFFIX"))
    return recipe_tree.CopyEnv.make(tree, root / "venv")


def dampnet(copy_env, *args: str, timeout: float = 600) -> str:
    """The copy's `dampnet ARGS`; its stdout (the run must succeed)."""
    proc = copy_env.run("-m", "dampnet.cli", *map(str, args), timeout=timeout)
    assert proc.returncode == 0, f"dampnet {' '.join(map(str, args))}\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}"
    return proc.stdout


def words(text: str) -> str:
    return " ".join(text.split())


def test_the_built_in_road_and_law_are_listed_and_run_by_the_cli(copy_env, tmp_path):
    help_ = words(dampnet(copy_env, "simulate", "--help"))
    assert "kerb" in help_ and "passive_mid" in help_
    dampnet(copy_env, "simulate", "truth", "--road", "kerb:height_m=0.05", "--control", "passive_mid",
            "--out", tmp_path / "run")
    meta = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert meta["road"]["input"] == "kerb" and meta["road"]["height_m"] == 0.05 and meta["law"] == "passive_mid"
    alias = copy_env.run("-c", "from dampnet.recipes import roads; print(roads.parse('curb').kind.name)")
    assert alias.returncode == 0 and alias.stdout.strip() == "kerb", alias.stderr   # its older spelling


def test_the_built_in_manoeuvre_runs_in_dampnet_vehicle_and_a_sweep(copy_env, tmp_path):
    help_ = words(dampnet(copy_env, "vehicle", "--help"))
    assert "hump" in help_ and "--hump-height M" in help_
    runs = {}
    for height in ("0.01", "0.02"):
        out = tmp_path / f"hump{height}"
        printed = dampnet(copy_env, "vehicle", "linear:2500", "--test", "hump", "--hump-height", height,
                          "--dt", "0.002", "--out", out)
        assert "running hump" in printed
        runs[height] = json.loads((out / "metrics.json").read_text())
        assert runs[height]["maneuver"]["hump_height_m"] == float(height)
    # the setting reaches the physics: a linear car on a twice as high hump, about twice the acceleration
    ratio = runs["0.02"]["metrics"]["hump_acc_peak_m_s2"] / runs["0.01"]["metrics"]["hump_acc_peak_m_s2"]
    assert 1.8 < ratio < 2.2, ratio
    # a sweep on worker processes, which import recipes/maneuvers.py and so the built-in
    spec = tmp_path / "hump.toml"
    spec.write_text('[fullcar]\nmodels = ["linear:2500"]\ntests = ["hump"]\nhump_heights_m = [0.01, 0.02]\n'
                    'dt = 0.002\n')
    dampnet(copy_env, "sweep", spec, "--out", tmp_path / "sweep", "--workers", "1", "--quiet")
    with open(tmp_path / "sweep" / "results.csv", newline="") as f:
        rows = {float(r["hump_height_m"]): r for r in csv.DictReader(f)}
    assert set(rows) == {0.01, 0.02} and all(r["status"] == "ok" for r in rows.values())
    for height, run in runs.items():   # the sweep's cell is the CLI's run
        assert float(rows[float(height)]["hump_acc_peak_m_s2"]) == pytest.approx(
            run["metrics"]["hump_acc_peak_m_s2"], rel=1e-12)


def test_the_built_in_export_target_is_written_by_dampnet_export(copy_env, tmp_path):
    help_ = words(dampnet(copy_env, "export", "--help"))
    assert "--forces-csv OUT.csv" in help_ and "forces-csv (--forces-csv OUT.csv)" in help_
    model = ROOT / "export" / "dn_model_default.json"
    out = tmp_path / "f.csv"
    printed = dampnet(copy_env, "export", model, "--forces-csv", out, "--points", "5", "--header", tmp_path / "m.h")
    assert f"{out}: 5 forces [N]" in printed and (tmp_path / "m.h").is_file()
    with open(out, newline="") as f:
        rows = list(csv.DictReader(f))
    force = [float(r["force_n"]) for r in rows]
    assert len(rows) == 5 and force[-1] > force[2] > force[0]      # a damper's force grows with velocity


@pytest.fixture(scope="module")
def docs_regenerated(copy_env) -> subprocess.CompletedProcess:
    """The training-option recipe's step 3 in the copy (its docs' table regenerated by the command the
    recipe names), once; the copy's docs test as it ran before that step."""
    before = copy_env.run("-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                          "tests/python/test_training_options.py", "-k", "docs_table", timeout=600)
    regen = copy_env.run("-m", "dampnet.training.options_table", "docs/training.md")
    assert regen.returncode == 0 and "options table regenerated" in regen.stdout, regen.stderr
    return before


def test_the_training_option_reaches_the_cli_once_the_docs_are_regenerated(copy_env, docs_regenerated):
    """The recipe's three steps: the row (appended), its use (none: the option is only wired), the
    docs' table regenerated; the copy's docs test failed before that step (it passes after it, with
    the rest of the options' tests, among the registry-wide tests below)."""
    help_ = words(dampnet(copy_env, "train", "--help"))
    assert "--grad-clip" in help_ and "the largest gradient norm of an Adam step" in help_
    before = docs_regenerated
    assert before.returncode != 0 and "test_the_docs_table_is_the_options_table" in before.stdout, before.stdout[-2000:]
    assert "| grad_clip | `--grad-clip` | grad_clips |" in (copy_env.copy / "docs" / "training.md").read_text()


def test_the_copys_registry_wide_tests_pass(copy_env, docs_regenerated):
    proc = copy_env.run("-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                        "tests/python/test_roads_profiles.py", "tests/python/test_sim_names.py",
                        "tests/python/test_sweep_vehicle.py", "tests/python/test_public_api.py",
                        "tests/python/test_training_options.py", timeout=600)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-2000:]
    print(proc.stdout.strip().splitlines()[-1])
