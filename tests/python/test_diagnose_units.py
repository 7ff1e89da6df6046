"""Catalogue, additions and the derived features."""

import numpy as np
import pytest

from dampnet.diagnosis.catalogue import CANDIDATES
from dampnet.effects import additions
from dampnet.features import dahl_state, first_order_lag


def test_catalogue_ids_fixed():
    assert {"gas_spring", "thermal", "valve_lag", "friction", "compressibility"} <= set(CANDIDATES)


def test_additions():
    assert additions("gas_spring")["features"] == ["displacement"]
    a = additions("valve_lag", {"tau_s": 0.02}, control="current")
    assert a["features"] == ["current_lag"] and a["feature_params"]["control_lag_tau_s"] == 0.02
    with pytest.raises(ValueError):
        additions("nope")


def test_lag_and_dahl():
    x = np.r_[np.zeros(10), np.ones(100)]
    y = first_order_lag(x, 0.001, 0.01)
    assert y[0] == 0 and abs(y[10 + 10] - (1 - np.exp(-1.1))) < 0.05
    v = np.r_[np.full(100, 0.1), np.full(100, -0.1)]
    z = dahl_state(v, 0.001, 1e-3)
    # Dahl: z -> sgn(v) with decay exp(-|v| dt / x0) per sample; 100 samples at -0.1 m/s
    # from z = 1 leave z = -1 + 2 exp(-10) (analytic, to rounding).
    assert z[99] == pytest.approx(1) and z[-1] == pytest.approx(-1 + 2 * np.exp(-10.0), rel=1e-9)
