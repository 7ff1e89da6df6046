"""The lookup-table baseline: bilinear interpolation with clamping (as the C++ table), and its fit
from rig data (peak force against peak velocity per voltage)."""

import json

import numpy as np
import pytest

from dampnet.rig import generate
from dampnet.evaluation.lookup import LookupTable, fit_lookup, peak_points
from dampnet.evaluation.metrics import error_stats

V = np.array([-0.2, 0.0, 0.1, 0.3])
U = np.array([0.0, 1.0, 5.0])
# forces[j][i] at voltages[j], velocities[i]: a function bilinear in (v, u) on each cell
F = np.array([[-200.0, 0.0, 100.0, 250.0],
              [-300.0, 10.0, 180.0, 400.0],
              [-900.0, 50.0, 600.0, 1500.0]])


def brute_bilinear(v, u):
    """Independent bilinear interpolation: explicit cell search and the four-corner formula."""
    v = min(max(v, V[0]), V[-1])
    u = min(max(u, U[0]), U[-1])
    i = max(k for k in range(len(V) - 1) if V[k] <= v)
    j = max(k for k in range(len(U) - 1) if U[k] <= u)
    s = (v - V[i]) / (V[i + 1] - V[i])
    t = (u - U[j]) / (U[j + 1] - U[j])
    return ((1 - s) * (1 - t) * F[j, i] + s * (1 - t) * F[j, i + 1]
            + (1 - s) * t * F[j + 1, i] + s * t * F[j + 1, i + 1])


def test_grid_points_are_reproduced_exactly():
    table = LookupTable(V, U, F)
    vv, uu = np.meshgrid(V, U)
    np.testing.assert_array_equal(table.force(vv, uu), F)


def test_interpolation_matches_an_independent_bilinear_and_clamps_outside():
    table = LookupTable(V, U, F)
    rng = np.random.default_rng(0)
    v = rng.uniform(-0.5, 0.6, 500)  # about a third outside the grid
    u = rng.uniform(-2, 7, 500)
    expect = np.array([brute_bilinear(a, b) for a, b in zip(v, u)])
    np.testing.assert_allclose(table.force(v, u), expect, rtol=1e-13, atol=1e-10)
    # clamped: beyond the corner the corner value, beyond an edge the edge curve
    assert table.force(1.0, 10.0) == F[-1, -1]
    assert table.force(-1.0, -1.0) == F[0, 0]
    assert table.force(0.05, 9.0) == pytest.approx(0.5 * (F[-1, 1] + F[-1, 2]))


def test_single_voltage_is_constant_along_voltage():
    table = LookupTable(V, [2.0], F[1:2])
    np.testing.assert_allclose(table.force(V, np.full(4, -3.0)), F[1])
    np.testing.assert_allclose(table.force(0.2, 4.0), 0.5 * (F[1, 2] + F[1, 3]))


def test_bad_tables_are_refused():
    with pytest.raises(ValueError, match="shape"):
        LookupTable(V, U, F.T)
    with pytest.raises(ValueError, match="increasing"):
        LookupTable(V[::-1], U, F)


def test_dict_round_trip_and_layout_note():
    table = LookupTable(V, U, F)
    d = json.loads(table.to_json())
    assert d["units"] == {"velocities": "m/s", "voltages": "V", "forces": "N"}
    back = LookupTable.from_dict(d)
    np.testing.assert_array_equal(back.forces, F)
    np.testing.assert_array_equal(back.velocities, V)


@pytest.fixture(scope="module")
def quick():
    return generate("quick", seed=1, truth_channels=True)


def test_fit_recovers_peak_points_of_every_test(quick):
    table = fit_lookup(quick)
    assert list(table.voltages) == [0.0, 2.25, 5.0]
    assert table.forces.shape == (3, table.velocities.size)
    assert 0.0 in table.velocities and table.velocities.size == 7  # 3 frequencies x 2 signs + 0
    for t in quick.tests:
        (vr, fr), (vc, fc) = peak_points(t)
        # the table at a test's own peak (velocity, voltage) is its peak force (grid values are
        # medians of near-equal peak velocities, so allow the slope times the velocity spread)
        assert table.force(vr, t.control_nominal) == pytest.approx(fr, rel=0.03, abs=15)
        assert table.force(vc, t.control_nominal) == pytest.approx(fc, rel=0.03, abs=15)
        # and the peaks are the true (noise-free) ones, not noise maxima
        assert fr == pytest.approx(t.channels["true_force"].max(), rel=0.01, abs=10)


def test_fitted_table_is_a_fair_baseline(quick):
    """Far better than a constant force, worse than the noise (it has no hysteresis)."""
    table = fit_lookup(quick)
    f = quick.concat("force")
    pred = np.concatenate([table.predict_test(t) for t in quick.tests])
    s = error_stats(pred, f)
    const = error_stats(np.full_like(f, f.mean()), f)
    assert s["nrmse"] < 0.25 * const["nrmse"]
    assert s["rmse_n"] > 3 * 4.45
