"""Training of MLP damper models (issue 5): LM, Bayesian regularisation, SCG, Adam.

fit(X, y, features=...) -> (MlpModel, TrainInfo) is the entry point;
torch_forward(model, X) is an independent float64 reference forward pass;
features are built by dampnet.features.feature_matrix; the dataset-to-model pipeline
(hold-out, decimation, physics terms) is dampnet.training.pipeline.train_dataset.
"""

from dampnet.training.fit import ALGORITHMS, TrainInfo, fit
from dampnet.training.metrics import nrmse
from dampnet.training.torch_reference import torch_forward

__all__ = ["ALGORITHMS", "TrainInfo", "fit", "nrmse", "torch_forward"]
