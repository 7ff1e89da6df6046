"""Force of a (hybrid) model on dyno data: MLP(features) + the model's physics terms."""

from __future__ import annotations

import numpy as np

from dampnet.data import DataError, DynoTest
from dampnet.features import feature_matrix
from dampnet.model import MlpModel, ModelError
from dampnet.terms import terms_force


def terms_force_checked(terms, displacement, **inputs) -> np.ndarray:
    """terms_force [N] with a bad term as ModelError (a model's terms come from its file);
    inputs: the others a term reads (a valve: v [m/s], u [V or A])."""
    try:
        return terms_force(terms, np.asarray(displacement, dtype=np.float64), **inputs)
    except ValueError as e:
        raise ModelError(f"physics terms: {e}") from None


def term_inputs(test: DynoTest) -> dict[str, np.ndarray]:
    """What a model's physics terms read from a test besides its displacement: the velocity v [m/s]
    and the control u [V or A] (a valve term's; the others ignore them)."""
    return {"v": test.channels["velocity"], "u": test.control}


def model_inputs(model: MlpModel, test: DynoTest) -> np.ndarray:
    """The network's inputs [n, n_inputs] on a test, as the model sees them (its features and
    their parameters, its acceleration window; via the feature registry)."""
    return feature_matrix([test], model.features, model.feature_params,
                          model.meta.get("data", {}).get("acceleration_window_s"))


def predict_force(model: MlpModel, test_or_features, displacement: np.ndarray | None = None,
                  **inputs) -> np.ndarray:
    """Force [N] of a (hybrid) model: MLP(features) + sum of the model's physics terms.

    `test_or_features`: a DynoTest (features built via the registry; a missing
    feature raises DataError) or a feature matrix [n, n_inputs] in the model's
    feature order, in which case a hybrid model also needs `displacement` [m] (and a valve
    term v [m/s] and u [V or A] in `inputs`; from a DynoTest its velocity and control).
    """
    if isinstance(test_or_features, DynoTest):
        test = test_or_features
        X = model_inputs(model, test)
        if model.terms:
            if "displacement" not in test.channels:
                raise DataError(f"test {test.test_id}: the model's physics terms need a displacement "
                                "channel, which the data do not have")
            displacement = test.channels["displacement"]
            inputs = {**term_inputs(test), **inputs}
    else:
        X = np.atleast_2d(np.asarray(test_or_features, dtype=np.float64))
    y = model.predict(X)
    if model.terms:
        if displacement is None:
            raise ModelError("this model has physics terms: pass displacement [m] with the features")
        y = y + terms_force_checked(model.terms, np.asarray(displacement, dtype=np.float64).ravel(),
                                    **{k: np.asarray(a, dtype=np.float64).ravel() for k, a in inputs.items()})
    return y
