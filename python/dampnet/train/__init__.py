"""Training of MLP damper models (issue 5): LM, Bayesian regularisation, SCG, Adam.

fit(X, y, features=...) -> (MlpModel, TrainInfo) is the entry point;
torch_forward(model, X) is an independent float64 reference forward pass;
features_matrix(tests, features) builds X from dyno tests via the feature
registry in dampnet.train.features.
"""

from dampnet.train.features import FEATURES, features_matrix, register_feature, target_vector
from dampnet.train.fit import ALGORITHMS, TrainInfo, fit
from dampnet.train.metrics import nrmse
from dampnet.train.reference import torch_forward

__all__ = ["ALGORITHMS", "FEATURES", "TrainInfo", "features_matrix", "fit", "nrmse",
           "register_feature", "target_vector", "torch_forward"]
