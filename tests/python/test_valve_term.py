"""The valve term (issue 54 items 1 and 4): a bleed orifice in parallel with a preloaded blow-off
valve, per direction, scaled by the control, its blow-off law straight or digressive (the
digressions k_d, 10 parameters; 8, a valve written before them, is k_d = 0) (dn_xmacro.h
DN_TERM_LIST "valve"; cpp/include/dampnet/terms.hpp; python/dampnet/terms.py).

Checked against an independent reference (the law written out again here in numpy, piecewise
and branchy, not dampnet.terms' vectorised form): the C++ force (Damper.forces, the C ABI's
dn_damper_terms_grad through _core.Damper.terms_grad) and the numpy mirror equal it to 1e-12;
the runtime's derivatives dF/dv, dF/du equal central finite differences; the law is C1 at the
knee (one-sided slopes equal) and at v = 0, and never falls with the speed; an 8-parameter valve
gives exactly the force of the same valve with k_d = 0 (10 parameters); the force is finite and bounded for any input
(NaN, +-inf, huge), and a damper refuses a non-finite v or u the valve reads; a hybrid model
with a valve term gives the same forces in the pybind damper, the exported header compiled on
the host with the C library (python/dampnet/demo/controller.c), the damper FMU (FMPy) and the
quarter-car loop; the term's code cross-built for the Cortex-M4F runs in QEMU and equals the host.
ONNX graphs carry no physics term of any kind (listed in their metadata only: docs/export.md),
so ONNX is checked for listing the valve term, not for its force."""

from __future__ import annotations

import json
import math
import re
import subprocess

import numpy as np
import pytest

from cbuild import ROOT, compile_program
from dampnet import _core, terms as T
from dampnet.sim.quarter_car.loop import add_terms, damper_from_model
from loop_helpers import numpy_forward, random_model

#: v_k_ext [m/s], c_b_ext [N s^2/m^2], c_v_ext [N s/m], v_k_comp, c_b_comp, c_v_comp, g_num [1/V], g_den [1/V]
#: a digressive extension valve (c_v < 2 c_b v_k) and a progressive compression one (c_v > 2 c_b v_k);
#: voltage-controlled: the force falls from 1x at 0 V to g_num / g_den = 0.25x (the thesis's c(V) trend)
P = [0.12, 9.0e4, 2.5e3, 0.08, 4.0e4, 8.0e3, 0.5, 2.0]
#: current-controlled: affine gain 1 + 0.6 I (g_den = 0), harder with the current
P_CURRENT = [0.1, 5.0e4, 3.0e3, 0.1, 3.0e4, 2.0e3, 0.6, 0.0]
#: P with its blow-off laws bent (k_d_ext, k_d_comp [s/m]): the extension valve's slope halves 0.2 m/s
#: above its knee; the compression one, progressive at the knee, halves within 0.02 m/s (1 / k_d < v_k:
#: a bend added to the line's slope alone, c_v / (1 + k_d d) + m e, would fall there; the law does not)
P_DIG = P + [5.0, 50.0]
#: the current-controlled valve, digressive in extension only
P_CURRENT_DIG = P_CURRENT + [2.0, 0.0]
PARAMS = [P, P_CURRENT, P_DIG, P_CURRENT_DIG]
PARAM_IDS = ["voltage", "current", "voltage-digressive", "current-digressive"]
V_MAX, U_MAX = 50.0, 1000.0
rng = np.random.default_rng(54)


def reference(p, v, u):
    """The valve law written out per sample (independent of dampnet.terms and terms.hpp)."""
    kd_ext, kd_comp = (p[8], p[9]) if len(p) == 10 else (0.0, 0.0)

    def one(v, u):
        if math.isnan(v) or v == 0.0:
            return 0.0
        vk, cb, cv = p[0:3] if v > 0 else p[3:6]
        kd = kd_ext if v > 0 else kd_comp
        w = min(abs(v), V_MAX)
        if w <= vk:
            g = cb * w ** 2
        else:
            x = kd * (w - vk)  # the valve's opening z = ln(1 + x) / k_d (its limit w - v_k at x = 0)
            z = (w - vk) * (math.log1p(x) / x) if x != 0 else (w - vk)  # (x < 0: finite differences)
            g = cb * vk ** 2 + cv * z + (2 * cb * vk - cv) * vk * (-math.expm1(-z / vk))
        uc = 0.0 if math.isnan(u) else min(max(u, 0.0), U_MAX)
        s = (1 + p[6] * uc) / (1 + p[7] * uc)
        return math.copysign(s * g, v)
    v, u = np.broadcast_arrays(np.asarray(v, float), np.asarray(u, float))
    return np.array([one(a, b) for a, b in zip(v.ravel(), u.ravel())]).reshape(v.shape)


def cpp_force(p, v, u, x=0.0):
    """The force of a damper holding the valve term alone (Damper.linear(0) + term)."""
    d = add_terms(_core.Damper.linear(0.0), [{"kind": "valve", "params": p}])
    v = np.asarray(v, float)
    f, st, _ = d.forces(np.broadcast_to(x, v.shape), v, 0.0, np.asarray(u, float), 0.0, 20.0)
    return f, st


def cpp_grad(p, v, u, x=0.0):
    """(F, dF/dx, dF/dv, dF/du, status) of the C ABI's dn_damper_terms_grad."""
    d = add_terms(_core.Damper.linear(0.0), [{"kind": "valve", "params": p}])
    return d.terms_grad(np.broadcast_to(x, np.shape(v)).astype(float), np.asarray(v, float), np.asarray(u, float))


def random_inputs(n=4000):
    """Velocities over both directions, many near the knees and a few beyond the clamp; controls
    over the range and beyond it (negative, above U_MAX)."""
    v = np.concatenate([rng.uniform(-3, 3, n // 2), rng.choice([-1, 1], n // 4) * rng.uniform(0.05, 0.15, n // 4),
                        rng.uniform(-80, 80, n // 4)])
    u = np.concatenate([rng.uniform(-1, 12, n - 20), rng.uniform(1000, 2000, 10), rng.uniform(-50, -1, 10)])
    return v, rng.permutation(u)


@pytest.mark.parametrize("p", PARAMS, ids=PARAM_IDS)
def test_force_equals_the_independent_reference(p):
    """The C++ force (Damper.forces and dn_damper_terms_grad) and dampnet.terms' numpy force equal
    the reference to 1e-12 relative on random inputs, straight and digressive. Cost: 0.05 s."""
    v, u = random_inputs()
    ref = reference(p, v, u)
    f, st = cpp_force(p, v, u)
    assert np.all(st == 0)
    np.testing.assert_allclose(f, ref, rtol=1e-12, atol=1e-12)
    g = cpp_grad(p, v, u)
    assert np.all(g[4] == 0)
    np.testing.assert_allclose(g[0], ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(T.term_force({"kind": "valve", "params": p}, 0 * v, v, u=u), ref, rtol=1e-12,
                               atol=1e-12)
    # dissipative (F v >= 0), resisting extension and compression, and the control acts
    assert np.all(ref * v >= 0) and np.ptp(ref) > 1e3
    lo, hi = reference(p, 1.0, 0.0), reference(p, 1.0, 5.0)
    assert (hi < 0.5 * lo) if p[7] > 0 else (hi > 3.5 * lo)


@pytest.mark.parametrize("p", PARAMS, ids=PARAM_IDS)
def test_derivative_equals_finite_differences(p):
    """dF/dv and dF/du of the runtime (dn_damper_terms_grad) equal central finite differences of
    the reference force, dF/dx and dF/da are 0 (force_da's dF/da of terms), and the numpy
    mirror's valve_gradient equals the runtime's to 1e-12. Inputs away from the knee, 0 and the
    clamps by more than the difference step; dF/dv >= 0 everywhere (the digressive compression
    valve of P_DIG is progressive at its knee and bends within less than v_k). Cost: 0.1 s."""
    v, u = rng.uniform(-3, 3, 3000), rng.uniform(0.01, 12, 3000)
    away = (np.abs(np.abs(v) - np.where(v > 0, p[0], p[3])) > 1e-3) & (np.abs(v) > 1e-3)
    v, u = v[away], u[away]
    f, gx, gv, gu, st = cpp_grad(p, v, u)
    assert np.all(st == 0) and np.all(gx == 0)
    hv, hu = 1e-6 * np.maximum(np.abs(v), 1e-2), 1e-6 * np.maximum(u, 1.0)
    fd_v = (reference(p, v + hv, u) - reference(p, v - hv, u)) / (2 * hv)
    fd_u = (reference(p, v, u + hu) - reference(p, v, u - hu)) / (2 * hu)
    np.testing.assert_allclose(gv, fd_v, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd_v)))
    np.testing.assert_allclose(gu, fd_u, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd_u)))
    assert np.all(gv >= 0)  # the force never falls with the speed
    F, dv, du = T.valve_gradient(p, v, u)
    np.testing.assert_allclose(F, f, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dv, gv, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(du, gu, rtol=1e-12, atol=1e-12)
    # no term reads the acceleration: the hybrid damper's force does not move with a
    d = add_terms(_core.Damper.linear(0.0), [{"kind": "valve", "params": p}])
    f_a = d.forces(0.0, v, rng.uniform(-500, 500, v.size), u, 0.0, 20.0)[0]
    np.testing.assert_array_equal(f_a, f)


CURVATURE_PROGRAM = r"""#include <cstdio>
#include "dampnet/terms.hpp"
// argv: the valve's parameters; stdin: "v u" lines; stdout: d2F/du2 of the valve alone, and of
// the valve with a position polynomial (which does not read u), as terms::sum_grad gives them
int main(int argc, char** argv) {
  double p[DN_MAX_TERM_PARAMS] = {};
  for (int i = 1; i < argc && i <= DN_MAX_TERM_PARAMS; ++i) std::sscanf(argv[i], "%lf", &p[i - 1]);
  const double poly[4] = {-150.0, 3000.0, 0.0, 0.0};
  dampnet::Term t[2];
  if (dampnet::terms::make(t[0], "valve", p, argc - 1) != DN_OK ||
      dampnet::terms::make(t[1], "position_poly", poly, 4) != DN_OK)
    return 1;
  double v = 0, u = 0;
  while (std::scanf("%lf %lf", &v, &u) == 2) {
    dn_damper_input in{};
    in.x = 0.01, in.v = v, in.u = u;
    double g[3], c1 = 0, c2 = 0;
    dampnet::terms::sum_grad(t, 1, in, g, &c1);
    dampnet::terms::sum_grad(t, 2, in, g, &c2);
    std::printf("%.17g %.17g\n", c1, c2);
  }
  return 0;
}
"""


@pytest.fixture(scope="module")
def curvature_program(tmp_path_factory):
    d = tmp_path_factory.mktemp("valve_curvature")
    (d / "curv.cpp").write_text(CURVATURE_PROGRAM)
    return compile_program([d / "curv.cpp"], d / "curv", cxx=True, include_dirs=[ROOT / "cpp" / "include"])


@pytest.mark.parametrize("p", PARAMS, ids=PARAM_IDS)
def test_curvature_in_the_control_equals_finite_differences(p, curvature_program):
    """d2F/du2 of the runtime's valve (terms::sum_grad's curvature, which the inverse's Halley
    steps use: f s''(u) / s(u)) equals the central second difference of the reference force
    (independent of terms.hpp) to 1e-5 of its scale; 0 where u is clamped (below 0, above
    DN_TERM_VALVE_U_MAX) or v is 0; a position polynomial beside it (which does not read u)
    adds nothing. A host program on terms.hpp (one g++ compile for the module, ~1 s)."""
    v = np.concatenate([rng.uniform(-3, 3, 600), [0.0, 0.3, -0.3, 0.3]])
    u = np.concatenate([rng.uniform(0.05, 12, 600), [2.0, -0.5, U_MAX + 5.0, 0.0]])
    text = "\n".join(f"{a:.17g} {b:.17g}" for a, b in zip(v, u))
    out = subprocess.run([str(curvature_program), *(f"{x:.17g}" for x in p)], input=text, capture_output=True,
                         text=True, check=True).stdout
    c1, c2 = np.array([[float(x) for x in line.split()] for line in out.splitlines()]).T
    np.testing.assert_array_equal(c1, c2)
    inside = slice(0, 600)
    h = 1e-3 * np.maximum(u[inside], 1.0)
    fd = (reference(p, v[inside], u[inside] + h) - 2 * reference(p, v[inside], u[inside])
          + reference(p, v[inside], u[inside] - h)) / h ** 2
    if p[7] == 0:  # an affine gain (g_den = 0): no curvature, the difference its rounding alone
        assert np.all(c1 == 0)
        assert np.max(np.abs(fd)) <= 1e-6 * np.max(np.abs(reference(p, v[inside], u[inside])))
    else:
        scale = np.max(np.abs(fd))
        np.testing.assert_allclose(c1[inside], fd, rtol=1e-4, atol=1e-5 * scale)
    assert np.all(c1[600:] == 0)


@pytest.mark.parametrize("p", PARAMS, ids=PARAM_IDS)
def test_c1_at_the_knee_and_at_rest(p):
    """The one-sided slopes at each knee (v = +v_k_ext, -v_k_comp) equal each other and 2 c_b v_k
    (the bleed's), measured by one-sided differences of the runtime's force and by its
    derivative just inside and outside; the force is continuous there and at v = 0 (slope 0
    from both sides). A plain join of the bleed parabola and the valve line (slope c_v above
    the knee) would not be C1: its slopes differ by |2 c_b v_k - c_v| > 1e3 N s/m here, which
    the same comparison detects. Far above the knee the slope is the opening law's, c_v (straight)
    or c_v / (1 + k_d (w - v_k)) (digressive, up to the transition's share e of the opening z).
    Cost: 0.01 s."""
    u = 1.5
    s = (1 + p[6] * u) / (1 + p[7] * u)
    kds = (p[8], p[9]) if len(p) == 10 else (0.0, 0.0)
    for sign, vk, cb, cv, kd in ((1.0, p[0], p[1], p[2], kds[0]), (-1.0, p[3], p[4], p[5], kds[1])):
        knee = sign * vk
        h = 1e-7
        f0 = cpp_force(p, [knee], u)[0][0]
        right = (cpp_force(p, [knee + h], u)[0][0] - f0) / h
        left = (f0 - cpp_force(p, [knee - h], u)[0][0]) / h
        bleed_slope = s * 2 * cb * vk
        assert right == pytest.approx(bleed_slope, rel=1e-5) and left == pytest.approx(bleed_slope, rel=1e-5)
        gv = cpp_grad(p, np.array([knee - 1e-12, knee + 1e-12]), u)[2]
        assert gv[0] == pytest.approx(gv[1], rel=1e-9) and gv[0] == pytest.approx(bleed_slope, rel=1e-9)
        assert f0 == pytest.approx(sign * s * cb * vk ** 2, rel=1e-12)  # the preload force at the knee
        # far above the knee the valve's own opening law rules: slope c_v, or c_v / (1 + k_d d)
        far = cpp_grad(p, np.array([sign * 40 * vk]), u)[2][0]
        d = 39 * vk
        z = d if kd == 0 else math.log1p(kd * d) / kd
        e = math.exp(-z / vk)
        assert far == pytest.approx(s * (cv + (2 * cb * vk - cv) * e) / (1 + kd * d), rel=1e-9)
        if kd == 0:
            assert far == pytest.approx(s * cv, rel=1e-9)
        assert abs(2 * cb * vk - cv) > 1e3  # a kinked join would fail the slope check above
    f, _ = cpp_force(p, [-1e-9, 0.0, 1e-9], u)
    assert f[1] == 0.0 and abs(f[0]) < 1e-12 and abs(f[2]) < 1e-12


@pytest.mark.parametrize("p", [P, P_DIG, P + [1e6, 5e-324]], ids=["straight", "digressive", "extreme-k_d"])
def test_bounded_and_finite_for_any_input(p):
    """Huge finite v and u (+-1e308, denormals, 0) give a finite force and finite derivatives
    within the bound s_max g(50 m/s) (beyond the clamps the force is the clamp's), through
    Damper.forces and dn_damper_terms_grad; a non-finite v or u the valve reads is refused by
    both (DN_E_NONFINITE_INPUT, force and derivatives 0), a non-finite x it does not read is
    not; the numpy mirror gives the law's values for NaN and +-inf (NaN v: 0, NaN u: as 0).
    Straight, digressive, and with the digressions at their extremes (the largest accepted,
    1e6 s/m, and a denormal whose k_d (w - v_k) underflows). Cost: 0.01 s."""
    bad = [np.nan, np.inf, -np.inf, 1e308, -1e308, 0.0, 5e-324, -5e-324]
    v, u = (a.ravel() for a in np.meshgrid(bad, bad + [3.0]))
    finite = np.isfinite(v) & np.isfinite(u)
    f, gx, gv, gu, st = cpp_grad(p, v, u)
    assert np.all(st[finite] == 0) and np.all(st[~finite] == _core.DN_E_NONFINITE_INPUT)
    for a in (f, gx, gv, gu):
        assert np.all(np.isfinite(a)) and np.all(a[~finite] == 0)
    bound = max(reference(p, V_MAX, 0.0), -reference(p, -V_MAX, 0.0))  # s(u) <= 1 here (g_num < g_den)
    assert np.all(np.abs(f) <= bound * (1 + 1e-12))
    np.testing.assert_allclose(f[finite], reference(p, v[finite], u[finite]), rtol=1e-12, atol=0)
    assert reference(p, 1e308, 1e308) == reference(p, V_MAX, U_MAX) == f[(v == 1e308) & (u == 1e308)][0]
    fd, std = cpp_force(p, v, u)
    assert np.all(std[~finite] == _core.DN_E_NONFINITE_INPUT) and np.all(fd[~finite] == 0)
    assert np.all(std[finite] == 0) and np.all(np.abs(fd[finite]) <= bound * (1 + 1e-12))
    np.testing.assert_array_equal(fd[finite], f[finite])
    fx, stx = cpp_force(p, [0.5], 1.0, x=np.nan)
    assert stx[0] == 0 and fx[0] == pytest.approx(reference(p, 0.5, 1.0), rel=1e-12)
    # the numpy mirror on the non-finite inputs: the law's clamps and NaN rules, finite
    f_np = T.term_force({"kind": "valve", "params": p}, np.zeros_like(v), v, u=u)
    assert np.all(np.isfinite(f_np))
    np.testing.assert_allclose(f_np, reference(p, v, u), rtol=1e-12, atol=0)
    # the current-controlled gain (g_den = 0) is bounded by the control's clamp
    fc, _, _, _, stc = cpp_grad(P_CURRENT, [1e308, 1.0], [1e308, 1e308])
    assert np.all(stc == 0) and fc[1] == pytest.approx(reference(P_CURRENT, 1.0, U_MAX), rel=1e-12)
    assert fc[0] == pytest.approx(reference(P_CURRENT, V_MAX, U_MAX), rel=1e-12) and np.isfinite(fc[0])


@pytest.mark.parametrize("params, code", [
    (P[:7], "DN_E_SIZE"), ([0.0] + P[1:], "DN_E_PARAM"), (P[:3] + [-0.1] + P[4:], "DN_E_PARAM"),
    (P[:1] + [-1.0] + P[2:], "DN_E_PARAM"), (P[:5] + [-1.0] + P[6:], "DN_E_PARAM"),
    (P[:6] + [-0.1, 0.0], "DN_E_PARAM"), (P[:7] + [-0.1], "DN_E_PARAM"), (P[:2] + [np.inf] + P[3:], "NONFINITE"),
    (P + [1.0], "DN_E_SIZE"), (P + [1.0, 1.0, 1.0], "DN_E_SIZE"), (P + [-1e-9, 0.0], "DN_E_PARAM"),
    (P + [0.0, -1.0], "DN_E_PARAM"), (P + [1.000001e6, 0.0], "DN_E_PARAM"), (P + [0.0, np.inf], "NONFINITE"),
    (P + [0.0, np.nan], "NONFINITE"),
])
def test_bad_valve_parameters_are_refused(params, code):
    """The runtime and dampnet.terms refuse the same parameter sets: a count other than 8 or 10
    (the digressions both or neither), a knee velocity <= 0, a negative coefficient or gain, a
    digression outside [0, 1e6] s/m, a non-finite value. Cost: 0.01 s."""
    with pytest.raises(ValueError, match=code):
        _core.Damper.linear(1.0).add_term("valve", np.array(params, dtype=float))
    with pytest.raises(ValueError):
        T.validate({"kind": "valve", "params": params})


def test_registry_and_a_given_valve_in_fit_terms():
    """The runtime's kind list has the valve with 10 parameters, the same count as dampnet.terms
    (2 of them optional), and its text states the digressions' range as dampnet.terms checks it
    (the FMU's min/max read it); fit_terms takes a valve given with its parameters as fixed (its
    force, which reads v and u, is subtracted) and refuses to fit one from samples of one
    direction only. Cost: 0.9 s (importing scipy.optimize)."""
    from dampnet.export.fmu.description import range_in
    assert _core.TERM_KINDS["valve"][0] == 10 == len(T.KINDS["valve"].params) and T.KINDS["valve"].optional == 2
    for name in ("k_d_ext", "k_d_comp"):
        assert range_in(_core.TERM_KINDS["valve"][1], name, named_only=True) == (0.0, T.VALVE_K_D_MAX)
    x, v, u = np.zeros(50), rng.uniform(-1, 1, 50), rng.uniform(0, 5, 50)
    with pytest.raises(ValueError, match="extension and in compression"):
        T.fit_terms([{"kind": "valve"}], x, np.abs(v), u, v)
    y = reference(P, v, u) + 100.0 * x
    out = T.fit_terms([{"kind": "valve", "params": P}, {"kind": "position_poly"}], x + rng.uniform(-0.05, 0.05, 50),
                      v, u, y)
    assert out[0]["params"] == P and "fitted" not in out[0]


def test_an_8_parameter_valve_is_todays_straight_line():
    """A valve given 8 parameters (a model.json written before the digressions) loads in the
    runtime and dampnet.terms, and its force and derivatives are bit for bit those of the same
    valve with k_d_ext = k_d_comp = 0 (10 parameters), and the straight-line law (the reference
    without k_d) to 1e-12: the C ABI (Damper.forces, dn_damper_terms_grad) and the numpy mirror
    (term_force, valve_gradient, validate's padding). Cost: 0.01 s."""
    v, u = random_inputs()
    p10 = P + [0.0, 0.0]
    np.testing.assert_array_equal(T.validate({"kind": "valve", "params": P}), p10)
    np.testing.assert_array_equal(cpp_force(P, v, u)[0], cpp_force(p10, v, u)[0])
    for a, b in zip(cpp_grad(P, v, u), cpp_grad(p10, v, u)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(T.term_force({"kind": "valve", "params": P}, 0 * v, v, u=u),
                                  T.term_force({"kind": "valve", "params": p10}, 0 * v, v, u=u))
    for a, b in zip(T.valve_gradient(P, v, u), T.valve_gradient(p10, v, u)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(cpp_force(P, v, u)[0], reference(P, v, u), rtol=1e-12, atol=1e-12)
    # and a bend changes it only above the knees: below them the bleed alone, the same
    below = np.abs(v) < np.where(v > 0, P[0], P[3])
    np.testing.assert_array_equal(cpp_force(P_DIG, v[below], u[below])[0], cpp_force(P, v[below], u[below])[0])
    assert np.all(np.abs(cpp_force(P_DIG, v[~below], u[~below])[0]) < np.abs(cpp_force(P, v[~below], u[~below])[0]))


HYBRID_FEATURES = ["velocity", "acceleration", "voltage", "displacement"]
#: an 8-parameter valve (written before the digressions), a bump stop and a digressive valve
VALVE_TERMS = [{"kind": "valve", "params": P}, {"kind": "bump_stop", "params": [0.05, 2e5, 1.5]},
               {"kind": "valve", "params": P_DIG}]


@pytest.fixture(scope="module")
def hybrid():
    model = random_model(HYBRID_FEATURES, hidden=7, seed=11, terms=VALVE_TERMS)
    n = 400
    x = rng.uniform(-0.07, 0.07, n)
    v = rng.uniform(-2.5, 2.5, n)
    a = rng.uniform(-200, 200, n)
    u = rng.uniform(0, 5, n)
    return model, x, v, a, u


def test_hybrid_pybind_damper_equals_mlp_plus_reference(hybrid):
    """A hybrid model (4-input MLP + an 8-parameter valve + bump stop + a digressive valve) through
    damper_from_model equals the numpy MLP plus the reference valves plus the bump stop, to 1e-12
    relative. Cost: 0.01 s."""
    model, x, v, a, u = hybrid
    f, st, _ = damper_from_model(model).forces(x, v, a, u, u, 20.0)
    assert np.all(st >= 0)
    xf, k, n = VALVE_TERMS[1]["params"]
    bump = np.sign(x) * np.where(np.abs(x) > xf, k * np.maximum(np.abs(x) - xf, 0) ** n, 0.0)
    ref = numpy_forward(model, np.stack([v, a, u, x], axis=1)) + reference(P, v, u) + bump + reference(P_DIG, v, u)
    np.testing.assert_allclose(f, ref, rtol=1e-12, atol=1e-8)


def test_exported_header_with_the_c_library_equals_the_host(hybrid, tmp_path):
    """The exported header (dampnet.export.header) compiled on the host with the C library's
    sources and the demo's controller.c (dn_damper_add_term from the header's term rows,
    dn_damper_force) gives the pybind damper's forces to 1e-9 relative. Cost: 9 s (the compile)."""
    from dampnet.demo.cprogram import ROW_FIELDS
    from dampnet.export.header import write_header
    model, x, v, a, u = hybrid
    write_header(model, tmp_path / "model.h")
    lib = [ROOT / "cpp" / "src" / f for f in ("c_api_common.cpp", "c_api_mlp.cpp", "c_api_loop.cpp")]
    ctrl = ROOT / "python" / "dampnet" / "demo" / "controller.c"  # g++: C++, with the library's sources
    exe = compile_program([ctrl, *lib], tmp_path / "controller", cxx=True,
                          include_dirs=[ROOT / "cpp" / "include", ROOT / "cpp" / "src", tmp_path],
                          extra=["-DDN_STATIC", "-Wno-missing-field-initializers"])
    cols = {"x": x, "v": v, "a": a, "u": u, "u_lag": u, "temperature": np.full_like(x, 20.0),
            "v_lag": v, "z_fric": np.zeros_like(x)}
    rows = np.stack([cols[f] for f in ROW_FIELDS], axis=1)
    proc = subprocess.run([str(exe)], input="\n".join(" ".join(repr(float(c)) for c in r) for r in rows) + "\n",
                          capture_output=True, text=True, timeout=60, check=True)
    f_c = np.array([float(s) for s in proc.stdout.split()])
    f_host, st, _ = damper_from_model(model).forces(x, v, a, u, u, 20.0)
    assert np.all(st >= 0) and f_c.size == x.size
    np.testing.assert_allclose(f_c, f_host, rtol=1e-9, atol=1e-9)
    assert np.ptp(reference(P, v, u)) > 1e3  # the valve is a large part of the force


def test_damper_fmu_equals_the_host(hybrid, tmp_path):
    """The damper FMU (FMI 2 co-simulation, FMPy) of the hybrid model: the force read at each
    communication point equals the pybind damper's to 1e-9 N; its valve parameters are FMU
    parameters with the runtime's ranges (v_k_ext min 0, c_b_ext min 0, k_d_ext in [0, 1e6]), the
    8-parameter valve's 8 and the digressive one's 10. Cost: 6 s (the FMU build)."""
    import needs

    fmpy = needs.need_module("fmpy")
    from fmpy import read_model_description
    from dampnet.export.fmu import build_fmu
    import test_export_fmu as fx
    model, x, v, a, u = hybrid
    path = build_fmu(model, tmp_path / "valve.fmu", fmi=2)
    t = np.arange(x.size) * 1e-3
    f_fmu = fx.drive(path, (t, x, v, a, u))
    f_host, st, _ = damper_from_model(model).forces(x, v, a, u, u, 20.0)
    assert np.all(st >= 0)
    np.testing.assert_allclose(f_fmu, f_host, rtol=0, atol=1e-9)
    vs = {sv.name: sv for sv in read_model_description(str(path)).modelVariables}
    assert float(vs["valve_0.v_k_ext"].min) == 0.0 and float(vs["valve_0.c_b_ext"].min) == 0.0
    assert float(vs["valve_0.g_den"].start) == P[7] and "valve_0.k_d_ext" not in vs
    kd = vs["valve_2.k_d_comp"]
    assert (float(kd.min), float(kd.max), float(kd.start)) == (0.0, 1e6, P_DIG[9])
    assert fmpy is not None


def test_onnx_lists_the_valve_term_in_its_metadata(hybrid):
    """ONNX graphs hold the network only (no physics term of any kind is in the graph,
    docs/export.md): the valve term and its parameters are in the graph's metadata "terms".
    Cost: 2 s (importing onnx)."""
    import needs

    needs.need_module("onnx")
    from dampnet.export.onnx import onnx_graph
    model = hybrid[0]
    meta = {p.key: p.value for p in onnx_graph(model).metadata_props}
    assert json.loads(meta["terms"]) == VALVE_TERMS


def test_quarter_car_runs_the_valve_term(hybrid):
    """The quarter car (RK4, the linearised implicit acceleration of a model reading the
    acceleration, an external control stepping 0 -> 4 V) with the hybrid valve model over a
    bumpy road: every step succeeds and each step's reported force equals Damper.forces at the
    step's reported x, v, a and control to 1e-9 relative; the valve's share of it, the
    reference at (v, u), is large and follows the control. The terms' force at rest is the
    valve's 0 (static_term_force reads v = 0). Cost: 0.02 s."""
    from dampnet.sim.quarter_car.loop import QuarterCar, static_term_force
    model = hybrid[0]
    assert static_term_force(model.terms) == 0.0
    car = QuarterCar(damper_from_model(model), {"dt": 1e-3}, {"kind": "external"})
    n = 3000
    t = np.arange(n) * 1e-3
    road = 0.03 * np.sin(2 * np.pi * 1.7 * t) + 0.01 * np.sin(2 * np.pi * 11.0 * t)
    rate = 0.03 * 2 * np.pi * 1.7 * np.cos(2 * np.pi * 1.7 * t) + 0.01 * 2 * np.pi * 11.0 * np.cos(2 * np.pi * 11.0 * t)
    u = np.where(t < 1.5, 0.0, 4.0)
    res = car.simulate(road, rate, u)
    assert np.all(res["status"] >= 0)
    x, v, a, uc = res["x"], res["v"], res["a"], res["control"]
    f, st, _ = damper_from_model(model).forces(x, v, a, uc, uc, 20.0)
    np.testing.assert_allclose(res["force"], f, rtol=1e-9, atol=1e-9)
    valve = reference(P, v, uc)
    assert np.ptp(valve) > 200.0 and np.any(uc == 4.0) and np.any(uc == 0.0)


FIRMWARE = r"""// The valve term on the target: F, dF/dx, dF/dv, dF/du of stored inputs, as float bits in hex.
#include <stdint.h>
#include "dampnet/terms.hpp"
#include "valve_vectors.h"  // VALVE_P[10], VALVE_N, VALVE_IN[VALVE_N][2] (v, u)
extern "C" int dn_fw_semihost(int op, const void* arg);
static char line[64];
static int len = 0;
static void put(float f) {
  union { float f; uint32_t u; } b;
  b.f = f;
  for (int i = 7; i >= 0; --i) line[len++] = "0123456789abcdef"[(b.u >> (4 * i)) & 0xF];
  line[len++] = ' ';
}
extern "C" int main(void) {
  dampnet::real p[DN_MAX_TERM_PARAMS] = {};
  for (int i = 0; i < 10; ++i) p[i] = VALVE_P[i];
  if (dampnet::terms::validate_DN_TERM_VALVE(p) != DN_OK) return 3;
  for (int k = 0; k < VALVE_N; ++k) {
    dn_damper_input in{};
    in.v = VALVE_IN[k][0];
    in.u = VALVE_IN[k][1];
    dampnet::real g[3];
    const dampnet::real f = dampnet::terms::grad_DN_TERM_VALVE(p, in, g);
    len = 0;
    put(f); put(g[0]); put(g[1]); put(g[2]);
    line[len++] = '\n';
    line[len] = 0;
    dn_fw_semihost(0x04 /* SYS_WRITE0 */, line);
  }
  return 0;
}
"""


def test_cortex_m4f_firmware_equals_the_host(tmp_path):
    """The digressive valve term's code (terms.hpp) cross-built for the Cortex-M4F in float (DN_LOOP_FLOAT,
    the M4F preset's definitions, -Wdouble-promotion as an error) with the firmware's start-up
    code, run in QEMU (mps2-an386): its F, dF/dv, dF/du on 46 stored inputs (random, the knees,
    beyond both clamps) equal the host runtime's (double) to float precision (1e-5 of each
    quantity's largest magnitude), dF/dx is 0, and it links no software double routine and no
    C++ runtime. Cost: 0.9 s."""
    import firmware_lab as emb  # bench/firmware_lab.py (the conftest puts bench/ on the path)
    why = emb.toolchain_missing()
    if why:
        pytest.fail(why, pytrace=False)
    r = np.random.default_rng(1)
    v = np.concatenate([r.uniform(-3, 3, 40), [P[0], -P[3], 60.0, -60.0, 0.0, 1e30]]).astype(np.float32)
    u = np.concatenate([r.uniform(-1, 12, 40), [1.0, 1.0, 2000.0, -5.0, 3.0, 1e30]]).astype(np.float32)
    p32 = np.asarray(P_DIG, np.float32)
    (tmp_path / "valve_vectors.h").write_text(
        "static const float VALVE_P[10] = {" + ", ".join(f"{float(x)!r}f" for x in p32) + "};\n"
        f"#define VALVE_N {v.size}\nstatic const float VALVE_IN[VALVE_N][2] = {{"
        + ", ".join(f"{{{float(a)!r}f, {float(b)!r}f}}" for a, b in zip(v, u)) + "};\n")
    (tmp_path / "valve_fw.cpp").write_text(FIRMWARE)
    flags = emb.mcu.CPUS["cortex-m4"]["flags"].split()
    defines = [f"-D{d}" for d in emb.target_defines("cortex-m4", emb.DEFAULT_CAPS) if not d.startswith("DN_CAP_TERMS")]
    defines += ["-DDN_CAP_TERMS=2", "-DDN_STATIC"]
    emb_dir = ROOT / "cpp" / "embedded"
    subprocess.run(["arm-none-eabi-g++", "-std=c++17", "-O2", *flags, "-fno-exceptions", "-fno-rtti", "-Wall", "-Wextra",
                    "-Werror", "-Wdouble-promotion", *defines, f"-I{ROOT / 'cpp' / 'include'}", f"-I{tmp_path}", "-c",
                    str(tmp_path / "valve_fw.cpp"), "-o", str(tmp_path / "valve_fw.o")], check=True)
    subprocess.run(["arm-none-eabi-gcc", "-std=c99", "-O2", *flags, "-c", str(emb_dir / "startup.c"), "-o",
                    str(tmp_path / "startup.o")], check=True)
    elf = tmp_path / "valve_fw.elf"
    subprocess.run(["arm-none-eabi-gcc", *flags, "--specs=nano.specs", "-nostartfiles", "-Wl,--gc-sections",
                    f"-T{emb_dir / 'mps2.ld'}", str(tmp_path / "valve_fw.o"), str(tmp_path / "startup.o"), "-lm",
                    "-o", str(elf)], check=True)
    syms = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    assert not re.search(r"__aeabi_d|__cxa_|_Znw", syms), "software double or C++ runtime linked"
    out = emb.run(elf, "cortex-m4", icount=False)
    rows = [line.split() for line in out.splitlines() if re.fullmatch(r"([0-9a-f]{8} ){3}[0-9a-f]{8}", line.strip())]
    fw = np.array([[np.uint32(int(h, 16)).view(np.float32) for h in row] for row in rows], dtype=np.float64)
    assert fw.shape == (v.size, 4)
    f, gx, gv, gu, st = cpp_grad(p32.astype(np.float64).tolist(), v.astype(np.float64), u.astype(np.float64))
    assert np.all(st == 0) and np.all(fw[:, 1] == 0)
    for k, host in ((0, f), (2, gv), (3, gu)):
        np.testing.assert_allclose(fw[:, k], host, rtol=1e-5, atol=1e-5 * np.max(np.abs(host)))


@pytest.mark.parametrize("p", [P + [0.0, 0.0], P_DIG, P + [1e-5, 200.0]], ids=["straight", "digressive", "tiny-and-large-k_d"])
def test_parameter_jacobian_equals_finite_differences(p):
    """valve_param_jacobian (the nonlinear fit's Jacobian, dF/dp for the 10 parameters) equals
    central differences of the reference force, the digressions' columns also at k_d = 0 (the
    fit's start: a straight line) and where k_d (w - v_k) is small (its series). An 8-parameter
    valve has the same 10 columns as with k_d = 0. Cost: 0.3 s."""
    v, u = rng.uniform(-3, 3, 2000), rng.uniform(0, 8, 2000)
    J = T.valve_param_jacobian(p, v, u)
    if p[8] == p[9] == 0:
        np.testing.assert_array_equal(T.valve_param_jacobian(p[:8], v, u), J)
    for k in range(10):
        h = 1e-6 * max(abs(p[k]), 1.0 if k >= 8 else 0.0)
        hi, lo = list(p), list(p)
        hi[k] += h
        lo[k] -= h
        fd = (reference(hi, v, u) - reference(lo, v, u)) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd)))


@pytest.mark.parametrize("p", [P + [0.0, 0.0], P_DIG, P + [1e-5, 200.0]], ids=["straight", "digressive", "tiny-and-large-k_d"])
def test_the_fits_sample_evaluation_equals_the_term_bit_for_bit(p):
    """The valve fit's own evaluation (terms._ValveSamples: the samples split by direction and
    sorted by speed once, each side of the knee computed alone) gives the force and dF/dp of
    `_valve` and `valve_param_jacobian` exactly, in the samples' order, on samples at rest, at
    the knee, beyond the speed clamp and with the control outside its range; the Jacobian asked
    for after another force equals a fresh one. Cost: 0.1 s."""
    v = np.concatenate([rng.uniform(-3, 3, 3000), [0.0, 0.0, P[0], -P[3], 60.0, -70.0]])
    u = np.concatenate([rng.uniform(-1, 8, 3000), [0.0, 2.0, 3.0, 1500.0, 1.0, -2.0]])
    samples = T._ValveSamples(v, u)
    q = np.asarray(p, dtype=np.float64)
    other = q * 1.1
    for at in (q, other, q):   # the cache: a parameter change, and back
        np.testing.assert_array_equal(samples.force(at), T._valve(at, {"v": v, "u": u}))
        np.testing.assert_array_equal(samples.jacobian(at), T.valve_param_jacobian(at, v, u))


@pytest.mark.parametrize("p", [P, P_DIG], ids=["straight", "digressive"])
def test_fit_terms_recovers_a_valve_with_a_gas_spring(p):
    """fit_terms on noise-free force = valve(v, u) + gas spring(x) over six control levels:
    the valve's 10 parameters (nonlinear least squares, jointly with the polynomial's linear
    ones) and the polynomial come back (a straight valve to 1e-6, its digressions 0; a digressive
    one to 2e-3); a second free valve is refused. Cost: 1-3 s each."""
    rng = np.random.default_rng(54)
    if len(p) == 10:
        rng.uniform(size=4000)  # the draw this test was measured on (it followed the straight case)
    n = 4000
    t = np.arange(n) * 2e-4
    v = 1.5 * np.sin(2 * np.pi * 3 * t) * rng.uniform(0.2, 1.0, n)
    u = np.repeat([0.0, 1.0, 2.0, 3.0, 4.0, 5.0], -(-n // 6))[:n]
    x = 0.05 * np.sin(2 * np.pi * 1.3 * t)
    y = reference(p, v, u) + (-150.0 + 3000.0 * x)
    got = T.fit_terms([{"kind": "valve"}, {"kind": "position_poly"}], x, v, u, y)
    assert len(got[0]["params"]) == 10
    # the straight valve to 1e-6 (fitted straight: the digressive fit barely bends); the digressive
    # one to 2e-3 (trf stops on its step size short of the minimum with the 10 parameters: 1.1e-3 on
    # the compression valve, progressive and bent within 0.02 m/s, on rng 54's second draw)
    np.testing.assert_allclose(got[0]["params"], T.validate({"kind": "valve", "params": p}),
                               rtol=1e-6 if len(p) == 8 else 2e-3, atol=1e-7)
    if len(p) == 8:
        np.testing.assert_allclose(got[1]["params"], [-150.0, 3000.0, 0.0, 0.0], rtol=1e-6, atol=1e-3)
    else:  # the polynomial's force over the stroke to 0.05 N (of a force of kN: it takes the valve's last 1e-3)
        poly = T.term_force(got[1], x)
        np.testing.assert_allclose(poly, -150.0 + 3000.0 * x, rtol=0, atol=0.05)
    assert "nonlinear least squares" in got[0]["fitted"]
    with pytest.raises(ValueError, match="2 valve terms"):
        T.fit_terms([{"kind": "valve"}, {"kind": "valve"}], x, v, u, y)


def test_training_fits_a_valve_term_and_predicts_with_it():
    """dampnet training with a free valve term on the quick rig plan: the valve is fitted (10
    valid parameters the runtime accepts), the network learns the rest, and the prediction is
    MLP + the valve at the test's (v, u), equal to the runtime damper's force. Cost: 12 s (the rig data and the training)."""
    from dampnet.features import feature_matrix
    from dampnet.predict import predict_force
    from dampnet.rig import generate
    from dampnet.training.pipeline import train_dataset
    ds = generate("quick", seed=0)
    model, _, split = train_dataset(ds, terms=[{"kind": "valve"}], decimate=50, hidden=(4,), max_epochs=3)
    (term,) = model.terms
    assert term["kind"] == "valve" and len(term["params"]) == 10 and T._valve_check(np.array(term["params"])) is None
    t = split.holdout.tests[0]
    X = feature_matrix([t], model.features, model.feature_params)
    v, u = t.channels["velocity"], t.control
    valve = reference(term["params"], v, u)
    np.testing.assert_allclose(predict_force(model, t), model.predict(X) + valve, rtol=1e-12, atol=1e-9)
    assert np.ptp(valve) > 100.0  # the valve carries much of the rig damper's force
    d = damper_from_model(model)
    cols = {f: X[:, i] for i, f in enumerate(model.features)}
    a = cols.get("acceleration", np.zeros_like(v))
    f_rt, st, _ = d.forces(t.channels["displacement"], v, a, u, u, 20.0)
    assert np.all(st >= 0)
    np.testing.assert_allclose(f_rt, predict_force(model, t), rtol=1e-9, atol=1e-6)
