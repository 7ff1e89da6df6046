"""The package's top level: the public API by name, imported on first use."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

import dampnet

EXPECTED = {
    "load_model": "dampnet.modeldir.load_model",
    "save_model_dir": "dampnet.modeldir.save_model_dir",
    "load_dataset": "dampnet.data.readers.load_dataset",
    "train": "dampnet.recipes.training.train",   # the one training path (issue 31): returns the envelope too
    "evaluate": "dampnet.evaluation.report.evaluate",
    "diagnose": "dampnet.diagnosis.run.diagnose",
    "predict_force": "dampnet.predict.predict_force",
    "export_header": "dampnet.export.header.write_header",
    "QuarterCar": "dampnet.sim.quarter_car.loop.QuarterCar",
    "damper_from_model": "dampnet.sim.quarter_car.loop.damper_from_model",
    "MlpModel": "dampnet.model.MlpModel",
    "ModelError": "dampnet.model.ModelError",
    "DataError": "dampnet.data.types.DataError",
    "Dataset": "dampnet.data.types.Dataset",
    "DynoTest": "dampnet.data.types.DynoTest",
}
MODULES = {"rig": "dampnet.rig", "roads": "dampnet.sim.roads", "sim": "dampnet.sim"}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_each_public_name_is_the_object_it_documents(name):
    obj = getattr(dampnet, name)
    assert f"{obj.__module__}.{obj.__qualname__}" == EXPECTED[name]
    assert obj.__doc__, f"dampnet.{name} has no docstring"


def test_public_modules_and_all():
    for name, module in MODULES.items():
        assert getattr(dampnet, name).__name__ == module
    assert set(dampnet.__all__) == {*EXPECTED, *MODULES, "__version__"}
    assert set(dampnet.__all__) <= set(dir(dampnet))
    with pytest.raises(AttributeError, match="no attribute 'trian'"):
        dampnet.trian  # noqa: B018


def test_import_dampnet_is_light():
    """`import dampnet` (and so `dampnet --version`) loads neither torch nor the compiled runtime."""
    code = "import sys, dampnet; print(sorted(m for m in ('torch', 'dampnet._core', 'matplotlib', 'scipy') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


HEAVY = ("torch", "scipy", "matplotlib", "pandas", "dask", "onnx", "onnxruntime", "fmpy")


def test_help_imports_no_heavy_module():
    """`dampnet --help` and every `dampnet COMMAND --help` build their parsers without torch, scipy,
    matplotlib or the sweep's and export's libraries (issue 51: torch and scipy made `--help` take
    5 s of CPU); a command imports what it needs when it runs. One subprocess, ~1 s."""
    code = ("import contextlib, io, sys\n"
            "from dampnet.cli import COMMANDS, main\n"
            "for argv in [['--help']] + [[c.replace('_', '-'), '--help'] for c in COMMANDS]:\n"
            "    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
            "        main(argv)\n"
            f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]", proc.stdout


def test_the_parser_offers_every_training_algorithm():
    """--algorithm's choices come from the algorithms' names in words (no torch to import at parse
    time); they are the algorithms fit() has."""
    from dampnet.training import ALGORITHMS
    from dampnet.training.settings import ALGORITHM_NAMES

    assert set(ALGORITHM_NAMES) == set(ALGORITHMS)


def test_the_api_snippet_runs(tmp_path):
    """The package docstring's snippet, on the quick plan."""
    model = dampnet.load_model(dampnet.modeldir.default_model_path())
    data = dampnet.rig.generate("quick", seed=1)
    tables = dampnet.evaluate(model, data)
    assert 0 < tables["overall"]["nrmse"] < 1
    car = dampnet.QuarterCar(dampnet.damper_from_model(model), controller={"kind": "skyhook_onoff"})
    road = dampnet.roads.impulse()
    s = road.sample(car.dt)
    out = car.simulate(s.z, s.zdot)
    assert out["state"].shape[0] == len(s.z) and np.all(np.isfinite(out["force"]))


def test_a_moved_module_is_refused_naming_its_new_home():
    """Issue 31 moved modules into package families; the old dotted names are refused with the new
    one (never a bare "No module named"), and every new home imports."""
    import importlib

    assert len(dampnet.MOVED_MODULES) >= 12
    for old, new in dampnet.MOVED_MODULES.items():
        with pytest.raises(ModuleNotFoundError, match=rf"^{re.escape(old)} moved: it is {re.escape(new)} now$"):
            importlib.import_module(old)
        importlib.import_module(new.split(" ", 1)[0])
    with pytest.raises(ModuleNotFoundError, match=r"dampnet\.fullcar moved: it is dampnet\.sim\.full_car now"):
        importlib.import_module("dampnet.fullcar.runs")
    # `from dampnet import OLD` too (issue 49: it said only "cannot import name"), for every top-level one
    for old, new in dampnet.MOVED_MODULES.items():
        if old.count(".") == 1:
            with pytest.raises(ModuleNotFoundError, match=rf"^{re.escape(old)} moved: it is {re.escape(new)} now$"):
                exec(f"from dampnet import {old.split('.')[1]}", {})
    # names that only share a prefix with a moved one are untouched
    importlib.import_module("dampnet.sim.quarter_car.runs")
    importlib.import_module("dampnet.envelope")
    # the old command line (python -m) gets the same message
    r = subprocess.run([sys.executable, "-m", "dampnet.embedded", "run"], capture_output=True, text=True)
    assert r.returncode != 0 and "dampnet.embedded moved: it is dampnet.export.mcu" in r.stderr
