"""docs/recipes.md's road and control-law recipes applied as the built-ins the doc says they become
(issue 52 item 5): each recipe's code block, read from the doc, appended to the end of its
registry module (recipes/roads.py, recipes/control_laws.py) in a copy of the tree
(tests/python/recipe_tree.py), no other file edited. In the copy, with this tree's built
dampnet._core: the copy's registry-wide tests pass (every road builds, the plan-tests cases are
registry roads, the simulation's names), and its CLI lists both and runs them, with no test
registering anything.

test_recipes_runs.py runs the same blocks registered from a test (the path of a user's own module)
through every front end; the export-target and manoeuvre recipes need writer and builder
functions the doc leaves to the developer, and are proved that way only (test_recipes_export.py,
test_recipes_maneuvers.py). Cost: about 20 s (the copy, one CLI run, two test files).
"""

from __future__ import annotations

import json
import re
import shutil
import sysconfig
from pathlib import Path

import pytest

import recipe_tree
from cbuild import ROOT

RECIPES = ROOT / "docs" / "recipes.md"


def doc_block(section: str) -> str:
    """The first ```python block of docs/recipes.md's `## section`."""
    text = RECIPES.read_text()
    start = text.index(f"\n## {section}\n")
    m = re.compile(r"```python\n(.*?)```", re.S).search(text, start)
    assert m and m.start() < text.find("\n## ", start + 1), f"no python block in {section}"
    return m.group(1)


@pytest.fixture(scope="module")
def copy_env(tmp_path_factory) -> recipe_tree.CopyEnv:
    from dampnet import _core

    root = tmp_path_factory.mktemp("recipes-in-tree")
    tree = recipe_tree.copy_tree(root / "tree")
    pkg = tree / "python" / "dampnet"
    for module, section in (("roads", "Roads"), ("control_laws", "Control laws")):
        path = pkg / "recipes" / f"{module}.py"
        path.write_text(path.read_text() + f"\n\n# {section}: the recipe of docs/recipes.md, as a built-in\n"
                        + doc_block(section))
    shutil.copy2(_core.__file__, pkg / Path(_core.__file__).name)   # this tree's runtime: no C++ edited
    assert Path(_core.__file__).name.endswith(sysconfig.get_config_var("EXT_SUFFIX"))
    return recipe_tree.CopyEnv.make(tree, root / "venv")


def test_the_built_in_road_and_law_are_listed_and_run_by_the_cli(copy_env, tmp_path):
    help_ = copy_env.run("-m", "dampnet.cli", "simulate", "--help")
    assert help_.returncode == 0, help_.stderr
    words = " ".join(help_.stdout.split())
    assert "kerb" in words and "passive_mid" in words
    run = copy_env.run("-m", "dampnet.cli", "simulate", "truth", "--road", "kerb:height_m=0.05",
                       "--control", "passive_mid", "--out", str(tmp_path / "run"))
    assert run.returncode == 0, run.stdout + run.stderr
    meta = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert meta["road"]["input"] == "kerb" and meta["road"]["height_m"] == 0.05 and meta["law"] == "passive_mid"
    alias = copy_env.run("-c", "from dampnet.recipes import roads; print(roads.parse('curb').kind.name)")
    assert alias.returncode == 0 and alias.stdout.strip() == "kerb", alias.stderr   # its older spelling


def test_the_copys_registry_wide_tests_pass(copy_env):
    proc = copy_env.run("-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                        "tests/python/test_roads_profiles.py", "tests/python/test_sim_names.py", timeout=600)
    assert proc.returncode == 0, proc.stdout[-5000:] + proc.stderr[-2000:]
    print(proc.stdout.strip().splitlines()[-1])
