"""Training of MLP damper models (issue 5): LM, Bayesian regularisation, SCG, Adam.

fit(X, y, features=...) -> (MlpModel, TrainInfo) is the entry point;
torch_forward(model, X) is an independent float64 reference forward pass;
features are built by dampnet.features.feature_matrix; the dataset-to-model pipeline
(hold-out, decimation, physics terms) is dampnet.training.pipeline.train_dataset.

The names below are imported when first used (PEP 562), not with the package: the command line's
parser reads the training settings (dampnet.training.settings, restarts' score names) without
importing torch, so that `dampnet --help` answers at once. fit() lives in the module `fitting`:
a submodule named `fit` would take the function's place on the package once imported.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["ALGORITHMS", "TrainInfo", "fit", "nrmse", "torch_forward"]

_HOMES = {"ALGORITHMS": "dampnet.training.fitting", "TrainInfo": "dampnet.training.fitting",
          "fit": "dampnet.training.fitting",
          "nrmse": "dampnet.training.metrics", "torch_forward": "dampnet.training.torch_reference"}


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module 'dampnet.training' has no attribute {name!r}")
    return getattr(importlib.import_module(home), name)


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
