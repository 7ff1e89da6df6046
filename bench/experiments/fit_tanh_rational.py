"""Fit the float tanh of the AVX2 / AVX-512 MLP kernels (cpp/include/dampnet/activation.hpp):
tanh(x) ~ x P(y) / Q(y), y = x^2, |x| clamped to C, P of degree M, Q(y) = y^2 + q1 y + q0 (monic).

Linearised minimax (differential correction: minimise d subject to
|x P - tanh(x) Q| <= (d - rho(x)) Q_prev at the sample points, Q_prev the previous
iteration's denominator), with an allowance rho(x) = KAPPA |tanh x| 2^-24 for the float
rounding of the evaluation, so the fit spends its error where the rounding is smallest.
Fitted in s = (x / C)^2 for conditioning, then converted to y and Q made monic.

Usage: python bench/experiments/fit_tanh_rational.py [M C KAPPA]   (defaults 7 8.125 3: the kernel's)
Prints the coefficients for activation.hpp; the error of the float evaluation is measured by
tests/cpp/unit/test_activation.cpp (fast_tanh8) and tests/cpp/unit/test_mlp.cpp (through the kernel).
Needs numpy and scipy.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.optimize import linprog


def fit(m: int, n: int, c: float, kappa: float, n_pts: int = 5000, iters: int = 15):
    x = c * np.sin(np.linspace(0, np.pi / 2, n_pts))  # dense near the clamp
    x = np.unique(np.concatenate([x, np.linspace(0, c, n_pts)]))
    s = (x / c) ** 2
    t = np.tanh(x)
    rho = kappa * np.abs(t) * 2.0 ** -24
    a_mat = np.vander(s, m + 1, increasing=True) * x[:, None]
    b_mat = np.vander(s, n + 1, increasing=True)
    q_prev = np.ones_like(x)
    best = None
    for _ in range(iters):
        nv = m + n + 3  # P's m+1, Q's n+1, d
        cost = np.zeros(nv)
        cost[-1] = 1.0
        up = np.hstack([a_mat, -t[:, None] * b_mat, -q_prev[:, None]])
        lo = np.hstack([-a_mat, t[:, None] * b_mat, -q_prev[:, None]])
        a_eq = np.zeros((1, nv))
        a_eq[0, m + 1] = 1.0  # Q(0) = 1 while fitting
        r = linprog(cost, A_ub=np.vstack([up, lo]), b_ub=np.concatenate([-rho * q_prev, -rho * q_prev]),
                    A_eq=a_eq, b_eq=[1.0], bounds=[(None, None)] * (nv - 1) + [(0, None)], method="highs")
        a, b = r.x[: m + 1], r.x[m + 1: m + n + 2]
        q = b_mat @ b
        err = float(np.max(np.abs(a_mat @ a / q - t) + rho))  # the error with its rounding allowance
        q_prev = q
        if best is None or err < best[0]:
            best = (err, a, b)
    return best


def main(argv: list[str]) -> int:
    m, c, kappa = (int(argv[1]), float(argv[2]), float(argv[3])) if len(argv) > 3 else (7, 8.125, 3.0)
    err, a, b = fit(m, 2, c, kappa)
    p = np.array([a[k] / c ** (2 * k) for k in range(m + 1)])
    q = np.array([b[k] / c ** (2 * k) for k in range(3)])
    p, q = p / q[-1], q / q[-1]
    xs = np.linspace(0, 12, 400001)
    xc = np.minimum(xs, c)
    ys = xc * xc
    approx = xc * np.polyval(p[::-1], ys) / np.polyval(q[::-1], ys)
    print(f"P degree {m}, clamp {c}, kappa {kappa}: fit error + allowance {err:.3g}, "
          f"exact-arithmetic error on [0, 12] with the clamp {np.max(np.abs(approx - np.tanh(xs))):.3g}")
    print("kTanhP = {" + ", ".join(f"{v:.17g}" for v in p) + "}")
    print(f"kTanhQ0 = {q[0]:.17g}, kTanhQ1 = {q[1]:.17g}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
