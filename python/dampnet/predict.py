"""Force of a (hybrid) model on dyno data: MLP(features) + the model's physics terms."""

from __future__ import annotations

import numpy as np

from dampnet.data import DataError, DynoTest
from dampnet.features import feature_matrix
from dampnet.model import MlpModel, ModelError
from dampnet.terms import terms_force


def terms_force_checked(terms, displacement) -> np.ndarray:
    """terms_force [N] with a bad term as ModelError (a model's terms come from its file)."""
    try:
        return terms_force(terms, np.asarray(displacement, dtype=np.float64))
    except ValueError as e:
        raise ModelError(f"physics terms: {e}") from None


def predict_force(model: MlpModel, test_or_features, displacement: np.ndarray | None = None) -> np.ndarray:
    """Force [N] of a (hybrid) model: MLP(features) + sum of the model's physics terms.

    `test_or_features`: a DynoTest (features built via the registry; a missing
    feature raises DataError) or a feature matrix [n, n_inputs] in the model's
    feature order, in which case a hybrid model also needs `displacement` [m].
    """
    if isinstance(test_or_features, DynoTest):
        test = test_or_features
        X = feature_matrix([test], model.features, model.feature_params,
                           model.meta.get("data", {}).get("acceleration_window_s"))
        if model.terms:
            if "displacement" not in test.channels:
                raise DataError(f"test {test.test_id}: the model's physics terms need a displacement "
                                "channel, which the data do not have")
            displacement = test.channels["displacement"]
    else:
        X = np.atleast_2d(np.asarray(test_or_features, dtype=np.float64))
    y = model.predict(X)
    if model.terms:
        if displacement is None:
            raise ModelError("this model has physics terms: pass displacement [m] with the features")
        y = y + terms_force_checked(model.terms, np.asarray(displacement, dtype=np.float64).ravel())
    return y
