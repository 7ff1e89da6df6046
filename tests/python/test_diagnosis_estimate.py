"""The lag estimate (dampnet.diagnosis.estimate): its least-squares fits come from QR factors
stacked over groups of tests (issue 51: several times faster than a least-squares problem per
fit); checked against numpy's lstsq on the rows themselves. About 3 s in all."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet.diagnosis import estimate as E
from dampnet.diagnosis.basis import baseline_basis
from dampnet.rig import generate


@pytest.fixture(scope="module")
def quick():
    return generate("quick", seed=3, effects=["valve_lag"])


def _lstsq_sse(per_test) -> float:
    Z = np.vstack([z for z, _ in per_test])
    y = np.concatenate([f for _, f in per_test])
    lo, hi = Z.min(0), Z.max(0)
    X = baseline_basis(2 * (Z - lo) / np.where(hi > lo, hi - lo, 1) - 1, ["velocity", "acceleration", "control"])
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    return float(np.sum((y - X @ beta) ** 2))


def test_factor_sse_equals_lstsq_on_every_grid_tau(quick):
    """Both lags (the velocity's, the control's), every grid tau, the rows split into 3 groups; to
    1e-8 (lstsq cuts singular values below ~1e-12 of the largest; measured within 1e-10)."""
    n = len(quick.tests)
    for channel in ("velocity", quick.tests[0].control_name):
        for per_test in E._tau_rows(quick.tests, channel)[::3]:
            factors, rows = E._group_factors(per_test, [i % 3 for i in range(n)], 3)
            assert E._sse(factors, sum(rows)) == pytest.approx(_lstsq_sse(per_test), rel=1e-8)


def test_factor_sse_of_a_rank_deficient_basis_equals_lstsq():
    """Duplicate and zero columns (a constant input gives both: without lstsq's cut-off the fit
    takes round-off for signal), and fewer rows than columns (an exact fit)."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(500, 6))
    X = np.hstack([X, X[:, :2], np.zeros((500, 1))])
    y = X[:, 0] * 3 - X[:, 3] + rng.normal(scale=0.1, size=500)
    A = np.hstack([X, y[:, None]])
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    parts = [np.linalg.qr(A[k::4], mode="r") for k in range(4)]
    assert E._sse(parts, 500) == pytest.approx(float(np.sum((y - X @ beta) ** 2)), rel=1e-9)
    assert E._sse([np.linalg.qr(A[:5], mode="r")], 5) == pytest.approx(0.0, abs=1e-20)


def test_lag_with_spread_picks_the_lstsq_minimum(quick):
    """The whole estimate picks the grid tau whose lstsq fit is best, as the per-fit code did."""
    rows = E._tau_rows(quick.tests, quick.tests[0].control_name)
    best = E.GRID_S[int(np.argmin([_lstsq_sse(pt) for pt in rows]))]
    tau, spread = E.lag_with_spread(quick.tests, quick.tests[0].control_name)
    assert tau == best and spread is not None and spread > 0
    assert E.lag_with_spread(quick.tests[:1], "velocity")[1] is None
