"""What the diagnosis works on: the model's inputs, prediction and residual per test, at subsampled rows.

Everything is computed at the data's full sampling rate (lags and histories need
it) and then read at `rows` (an even stride, at most `rows_per_test` per test),
where the regressions are done.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dampnet.data import Dataset, DynoTest
from dampnet.data.preprocess import acceleration_of
from dampnet.features import check_features, feature_matrix
from dampnet.model import MlpModel
from dampnet.reference import mlp_forward
from dampnet.predict import term_inputs, terms_force_checked

#: Default number of rows per test at which residuals are regressed.
ROWS_PER_TEST = 600
#: Cap on all rows together (long test lists get fewer rows per test).
MAX_ROWS = 120_000


def model_force(model: MlpModel, X: np.ndarray, displacement: np.ndarray | None, **inputs) -> np.ndarray:
    """MLP (dampnet.reference, the kernel's function) plus the model's physics terms, which read the
    displacement [m] and `inputs` (dampnet.predict.term_inputs: a valve's v [m/s] and u)."""
    y = mlp_forward(model, X)
    if model.terms:
        y = y + terms_force_checked(model.terms, displacement, **inputs)
    return y


@dataclass
class TestData:
    test: DynoTest
    X: np.ndarray          # model inputs [n, k] at full rate
    pred: np.ndarray       # predicted force [N] at full rate
    resid: np.ndarray      # measured - predicted [N] at full rate
    rows: np.ndarray       # indices of the regression rows

    def ch(self, name: str) -> np.ndarray | None:
        """A channel (or the model-derived acceleration) at full rate, None if absent."""
        t = self.test
        if name == "acceleration" and name not in t.channels:
            return acceleration_of(t)
        return t.channels.get(name)


@dataclass
class Context:
    model: MlpModel
    dataset: Dataset
    tests: list[TestData]
    control_name: str
    notes: dict = field(default_factory=dict)

    @property
    def n_tests(self) -> int:
        return len(self.tests)

    def predict(self, i: int, replace: dict[str, np.ndarray] | None = None, rows_only: bool = True) -> np.ndarray:
        """The model's force for test i with some input columns replaced (arrays at full rate)."""
        td = self.tests[i]
        X = td.X[td.rows] if rows_only else td.X
        X = np.array(X)
        for name, col in (replace or {}).items():
            if name in self.model.features:
                j = self.model.features.index(name)
                X[:, j] = col[td.rows] if rows_only else col
        x = td.test.channels.get("displacement")
        inputs = term_inputs(td.test)
        if rows_only:
            x = None if x is None else x[td.rows]
            inputs = {k: a[td.rows] for k, a in inputs.items()}
        return model_force(self.model, X, x, **inputs)

    def at_rows(self, name: str) -> list[np.ndarray | None]:
        out = []
        for td in self.tests:
            c = td.ch(name)
            out.append(None if c is None else c[td.rows])
        return out

    def resid_rows(self) -> list[np.ndarray]:
        return [td.resid[td.rows] for td in self.tests]

    def pred_rows(self) -> list[np.ndarray]:
        return [td.pred[td.rows] for td in self.tests]

    def normalised_inputs(self, i: int) -> np.ndarray:
        """The model inputs at the rows, scaled as the network sees them (mapminmax to [-1, 1])."""
        m = self.model
        td = self.tests[i]
        z = (td.X[td.rows] - m.in_offset) * m.in_gain + m.in_ymin
        return np.clip(z, -1.5, 1.5)


def build_context(model: MlpModel, ds: Dataset, rows_per_test: int = ROWS_PER_TEST,
                  max_rows: int = MAX_ROWS) -> Context:
    """Inputs, prediction and residual of `model` on every test of `ds`."""
    check_features(model, ds)
    window = (model.meta.get("data") or {}).get("acceleration_window_s")
    per_test = max(50, min(rows_per_test, max_rows // max(1, len(ds.tests))))
    tests = []
    for t in ds.tests:
        X = feature_matrix([t], model.features, model.feature_params, window)
        pred = model_force(model, X, t.channels.get("displacement"), **term_inputs(t))
        resid = t.channels["force"] - pred
        n = len(t)
        stride = max(1, int(np.ceil(n / per_test)))
        rows = np.arange(stride // 2, n, stride)
        tests.append(TestData(test=t, X=X, pred=pred, resid=resid, rows=rows))
    control = ds.tests[0].control_name if ds.tests else "voltage"
    return Context(model=model, dataset=ds, tests=tests, control_name=control)
