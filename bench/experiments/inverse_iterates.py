"""The damper inverse's search (cpp/include/dampnet/damper.hpp, Damper::inverse) copied into numpy on
the default model, to count the Newton evaluations a reachable demand takes with other first
iterates and steps (issue 55 item 4): Newton or Halley steps (d2F/du2 from the same tanh values)
after a Newton, secant, Halley or inverse cubic Hermite first iterate, with the runtime's stopping
rules (the bracket, a step or the asked-for step under the tolerance; the force's rounding).
3,000 random reachable demands (test_damper_inverse's reachable_inputs, seed 1), double.

    python bench/experiments/inverse_iterates.py            # the tolerance 1e-6 of the range
    TOLR=1e-5 python bench/experiments/inverse_iterates.py  # a looser one
"""

import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "python"))
from test_damper_inverse import default_model, reachable_inputs, motion
from dampnet.sim.quarter_car.loop import damper_from_model
from dampnet.model import _folded_double
m = default_model(); fd = _folded_double(m)
W1, B1, WO, BO = fd["w1"], fd["b1"], fd["w_out"], fd["b_out"]
print("fold", fd["offsets_folded"], m.features, fd["sat_lo"], fd["sat_hi"])
d = damper_from_model(m, single=False)
lo, hi = d.control_range()
inp, dem = reachable_inputs(d, m, 3000, seed=1)
def F(v, a, u, order=1):
    x = np.clip(np.array([v, a, u]), fd["sat_lo"], fd["sat_hi"])
    if not fd["offsets_folded"]: x = x - fd["in_offset"]
    t = np.tanh(W1 @ x + B1); q = W1[:, 2]
    f = BO + WO @ t
    s = 1 - t * t
    d1 = WO @ (s * q); d2 = WO @ (-2 * t * s * q * q); d3 = WO @ ((6 * t * t - 2) * s * q ** 3)
    return f, d1, d2, d3
# check
fr = d.forces(**motion(inp), u=inp["u"])[0]
fe = np.array([F(inp["v"][i], inp["a"][i], inp["u"][i])[0] for i in range(50)])
print("emu err", np.abs(fe - fr[:50]).max())
TOL = float(os.environ.get("TOLR","1e-6")) * (hi - lo)

def solve(v, a, g0, first, step_kind):
    f_lo, d_lo, dd_lo, _ = F(v, a, lo); f_hi, d_hi, dd_hi, _ = F(v, a, hi)
    A, B, ga, gb = lo, hi, f_lo - g0, f_hi - g0
    if (ga > 0) == (gb > 0): return None
    near_lo = abs(ga) <= abs(gb)
    bu, bg = (A, ga) if near_lo else (B, gb)
    if first == "newton":
        x = bu - bg / (d_lo if near_lo else d_hi)
    elif first == "secant":
        x = A - ga * (B - A) / (gb - ga)
    elif first == "halley":
        dd = dd_lo if near_lo else dd_hi; d1 = d_lo if near_lo else d_hi
        x = bu - 2 * bg * d1 / (2 * d1 * d1 - bg * dd)
    elif first == "hermite_inv":  # inverse cubic Hermite u(F)
        t = (g0 - f_lo) / (f_hi - f_lo); h = f_hi - f_lo
        m0, m1 = h / d_lo if d_lo else 0, h / d_hi if d_hi else 0
        h00 = 2*t**3 - 3*t**2 + 1; h10 = t**3 - 2*t**2 + t; h01 = -2*t**3 + 3*t**2; h11 = t**3 - t**2
        x = lo + (hi - lo) * 0 + h00*lo + h10*m0 + h01*hi + h11*m1 - lo
    if not (A < x < B): x = A - ga * (B - A) / (gb - ga)
    if not (A < x < B): x = 0.5 * (A + B)
    n = 0; step = B - A
    for k in range(44):
        fx, dx, ddx, _ = F(v, a, x); n += 1
        g = fx - g0
        if abs(g) < 8e-16 * max(abs(f_lo), abs(f_hi)) or abs(step) <= TOL: break
        if (g > 0) == (ga > 0): A, ga = x, g
        else: B, gb = x, g
        if B - A <= TOL: break
        if step_kind == "halley":
            xn = x - 2 * g * dx / (2 * dx * dx - g * ddx)
        else:
            xn = x - g / dx
        if abs(xn - x) <= TOL and A < xn < B: break
        if not (A < xn < B): xn = 0.5 * (A + B)
        step = xn - x; x = xn
    return n
for first in ("newton", "secant", "halley", "hermite_inv"):
    for sk in ("newton", "halley"):
        ns = [solve(inp["v"][i], inp["a"][i], dem[i], first, sk) for i in range(3000)]
        ns = np.array([x for x in ns if x is not None])
        print(first, sk, "mean", ns.mean().round(3), "p90", np.percentile(ns, 90), "max", ns.max())
