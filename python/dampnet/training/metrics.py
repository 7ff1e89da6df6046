"""Error measures as in the thesis (Table 3)."""

from __future__ import annotations

import numpy as np


def nrmse(y_pred: np.ndarray, y_true: np.ndarray) -> float:
    """Root-mean-square error divided by the max-min range of y_true (dimensionless).

    A constant y_true (zero range) gives the plain RMSE.
    """
    y_pred, y_true = np.asarray(y_pred, dtype=np.float64), np.asarray(y_true, dtype=np.float64)
    rmse = float(np.sqrt(np.mean((y_pred - y_true) ** 2)))
    span = float(np.ptp(y_true)) if y_true.size else 0.0
    return rmse / span if span > 0 else rmse
