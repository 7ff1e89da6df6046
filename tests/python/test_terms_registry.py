"""dampnet.terms: each kind's formula once (force), the fit's columns derived from it, the
kinds the runtime's (dampnet.h DN_TERM_LIST via _core.TERM_KINDS)."""

from __future__ import annotations

import numpy as np
import pytest

from dampnet import _core, terms
from dampnet.terms import KINDS, Kind, fit_terms, terms_force

X = np.linspace(-0.06, 0.06, 801)  # displacement [m]
V = 0.8 * np.sin(np.linspace(0, 25, X.size))  # velocity [m/s]
U = np.where(np.arange(X.size) % 200 < 100, 1.0, 4.0)  # control [V]


def test_kinds_and_parameter_counts_are_the_runtimes():
    assert {k: len(kind.params) for k, kind in KINDS.items()} == {k: n for k, (n, _) in _core.TERM_KINDS.items()}


@pytest.mark.parametrize("name", sorted(k for k, kind in KINDS.items() if kind.fittable))  # the valve: nonlinear fit, no basis
def test_the_fit_basis_is_the_force_itself(name):
    """F(x; p) = basis(x, shape) @ p[linear] for random valid parameters: the fit's columns
    come from the one formula, so a formula change cannot leave the fit behind."""
    kind = KINDS[name]
    rng = np.random.default_rng(len(name))
    for _ in range(5):
        p = np.abs(rng.normal(size=len(kind.params))) + 0.5
        if name == "bump_stop":
            p[0] = 0.03
        assert kind.check(p) is None
        shape = tuple(p[[i for i in range(len(p)) if i not in kind.linear]])
        np.testing.assert_allclose(kind.basis(X, shape) @ p[list(kind.linear)],
                                   terms_force([{"kind": name, "params": p.tolist()}], X),
                                   rtol=1e-12, atol=1e-12)


def test_fit_terms_recovers_terms_on_their_grid():
    """A gas spring plus a bump stop whose shape lies on the grid, and a velocity force the
    velocity model absorbs: least squares recovers the parameters (no noise)."""
    xmax = float(np.max(np.abs(X)))
    true = [{"kind": "position_poly", "params": [-150.0, 2500.0, 8e3, 4e5]},
            {"kind": "bump_stop", "params": [0.8 * xmax, 3e6, 2.0]}]
    y = terms_force(true, X) + 900.0 * V + 120.0 * V * U
    got = fit_terms([{"kind": "position_poly"}, {"kind": "bump_stop"}], X, V, U, y)
    np.testing.assert_allclose(got[0]["params"], true[0]["params"], rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(got[1]["params"], true[1]["params"], rtol=1e-6)
    # given parameters are kept, the others fitted to what is left
    kept = fit_terms([true[0], {"kind": "bump_stop"}], X, V, U, y)
    assert kept[0]["params"] == true[0]["params"] and "fitted" not in kept[0]
    np.testing.assert_allclose(kept[1]["params"], true[1]["params"], rtol=1e-6)


def test_a_new_kind_is_fitted_from_its_kind_entry_alone(monkeypatch):
    """A kind added to KINDS only (linear and shape parameters declared) is fitted by fit_terms
    with no other edit."""
    def spring(p, q):
        return p[1] * (q["x"] - p[0])

    monkeypatch.setitem(KINDS, "offset_spring", Kind(
        ("x0 [m]", "k [N/m]"), spring, lambda p: None, "F = k (x - x0)", linear=(1,),
        shapes=lambda x: [(x0,) for x0 in (-0.01, 0.0, 0.01, 0.02)]))
    y = terms.terms_force([{"kind": "offset_spring", "params": [0.01, 5000.0]}], X) + 700.0 * V
    got = fit_terms([{"kind": "offset_spring"}], X, V, U, y)
    np.testing.assert_allclose(got[0]["params"], [0.01, 5000.0], rtol=1e-9)


def test_unknown_kinds_are_refused_naming_the_fittable_ones():
    with pytest.raises(ValueError, match="cannot fit physics term kind 'coulomb'.*bump_stop, position_poly"):
        fit_terms([{"kind": "coulomb"}], X, V, U, np.zeros_like(X))
