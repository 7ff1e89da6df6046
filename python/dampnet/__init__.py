"""dampnet: neural damper models from shock-dyno data.

Train the thesis's MLP (velocity, acceleration, voltage -> force), diagnose
what physics it misses, export it to a C header, and run it in a real-time
C++ quarter-car loop. Units are SI throughout.

    import dampnet
    model = dampnet.load_model("export/dn_model_default.json")   # or a model directory
    data = dampnet.rig.generate("quick", seed=1)                  # or dampnet.load_dataset(path)
    tables = dampnet.evaluate(model, data)                        # error tables [N, NRMSE]
    found = dampnet.diagnose(model, data)                         # the missing physical effect
    car = dampnet.QuarterCar(dampnet.damper_from_model(model), controller={"kind": "skyhook_onoff"})

The names are imported on first use, so `import dampnet` stays light (no torch, no
compiled runtime until a name that needs it is used). The package's layers, bottom up
(each imports only from the ones below: the import-linter contracts in pyproject.toml, run by
tests/python/test_layers.py with a check for import cycles):

  _core, schema, outputs, paths       the runtime's bindings and its registries; file I/O
  data                                dyno measurements: formats, readers, preprocessing
  features, terms                     model inputs (the runtime's registry plus their formulas), physics terms
  effects                             the one catalogue of physical effects (rig and diagnosis share its ids)
  model                               the model file
  envelope                            the training envelope: where the training data were, a run's coverage
  reference, predict                  the one numpy forward, force on a test
  rig                                 the virtual shock dyno (a plant)
  evaluation, training, diagnosis     error tables; the training pipeline; missing physics
  sim                                 the quarter car and the full vehicle: loops, dampers, roads, studies
  export, modeldir                    what `dampnet export` writes (header, ONNX, FMU, microcontroller
                                      folder); the model directory
  recipes                             the vocabulary of runs: roads, control laws, manoeuvres,
                                      training requests, export targets
  latency, sweep, campaign            the latency benchmarks; sweeps on Dask; dyno tests to run next
                                      (planned where a model is unsure, track replays)
  commands, demo, cli                 the command line
"""

from __future__ import annotations

import importlib
from typing import Any

# public name -> (module, attribute); attribute None: the module itself
_API: dict[str, tuple[str, str | None]] = {
    "MlpModel": ("dampnet.model", "MlpModel"),
    "ModelError": ("dampnet.model", "ModelError"),
    "DataError": ("dampnet.data", "DataError"),
    "Dataset": ("dampnet.data", "Dataset"),
    "DynoTest": ("dampnet.data", "DynoTest"),
    "load_model": ("dampnet.modeldir", "load_model"),
    "save_model_dir": ("dampnet.modeldir", "save_model_dir"),
    "load_dataset": ("dampnet.data", "load_dataset"),
    "train": ("dampnet.recipes.training", "train"),
    "evaluate": ("dampnet.evaluation.report", "evaluate"),
    "diagnose": ("dampnet.diagnosis.run", "diagnose"),
    "predict_force": ("dampnet.predict", "predict_force"),
    "export_header": ("dampnet.export.header", "write_header"),
    "QuarterCar": ("dampnet.sim.quarter_car.loop", "QuarterCar"),
    "damper_from_model": ("dampnet.sim.quarter_car.loop", "damper_from_model"),
    "rig": ("dampnet.rig", None),
    "roads": ("dampnet.sim.roads", None),
    "sim": ("dampnet.sim", None),
}

__all__ = sorted([*_API, "__version__"])

# modules that moved (issue 31's package families): importing an old name is refused with the new
# one, rather than a bare "No module named"
MOVED_MODULES: dict[str, str] = {
    "dampnet.artefacts": "dampnet.data.artefacts",
    "dampnet.planning": "dampnet.campaign.planning",
    "dampnet.replay": "dampnet.campaign.replay",
    "dampnet.coverage": "dampnet.envelope.coverage",
    "dampnet.coverage_plot": "dampnet.envelope.plot",
    "dampnet.envelope_grid": "dampnet.envelope.grid",
    "dampnet.ensemble": "dampnet.training.ensemble",
    "dampnet.fmu": "dampnet.export.fmu",
    "dampnet.embedded": "dampnet.export.mcu (the QEMU build/run lab: bench/firmware_lab.py in a source checkout)",
    "dampnet.fullcar": "dampnet.sim.full_car",
    "dampnet.sim.loop": "dampnet.sim.quarter_car.loop",
    "dampnet.sim.reference_loop": "dampnet.sim.quarter_car.reference_loop",
    "dampnet.sim.report": "dampnet.sim.quarter_car.report",
    "dampnet.sim.runs": "dampnet.sim.quarter_car.runs",
    "dampnet.sim.study": "dampnet.sim.quarter_car.study",
}


class _MovedModuleFinder:
    """A sys.meta_path finder that refuses a moved module's old name (and its submodules), naming
    where it lives now; every other name falls through to the normal finders."""

    @staticmethod
    def find_spec(fullname: str, path: Any = None, target: Any = None) -> None:
        for old, new in MOVED_MODULES.items():
            if fullname == old or fullname.startswith(old + "."):
                raise ModuleNotFoundError(f"{fullname} moved: it is {new}{fullname[len(old):]} now",
                                          name=fullname)
        return None


if not any(isinstance(f, _MovedModuleFinder) for f in __import__("sys").meta_path):
    __import__("sys").meta_path.insert(0, _MovedModuleFinder())



def _installed_version() -> str:
    """The installed distribution's version (importlib.metadata costs ~50 ms: read on first use)."""
    try:
        from importlib.metadata import version

        return version("dampnet")
    except Exception:  # running from a source tree without installation
        return "0.0.0+local"


def __getattr__(name: str) -> Any:
    if name == "__version__":
        globals()[name] = value = _installed_version()
        return value
    try:
        module, attr = _API[name]
    except KeyError:
        moved = MOVED_MODULES.get(f"dampnet.{name}")
        if moved is not None:  # `from dampnet import fullcar` names the new home, as `import dampnet.fullcar` does
            raise ModuleNotFoundError(f"dampnet.{name} moved: it is {moved} now", name=f"dampnet.{name}")
        raise AttributeError(f"module 'dampnet' has no attribute {name!r}") from None
    mod = importlib.import_module(module)
    value = mod if attr is None else getattr(mod, attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_API, "__version__"})
