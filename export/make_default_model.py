"""Regenerate export/dn_model_default.h (and its model.json twin), the header the C++ library builds its
examples and tests with when no trained model is at hand.

The model is a 3-30-1 tanh MLP (velocity [m/s], acceleration [m/s^2],
voltage [V] -> force [N]) fitted by least squares on its output layer
(random, seeded hidden layer) to the thesis's parametric semi-active damper,
eq. 1-3: F = c(V) v + F0 sgn(v), c = gamma / V + c_min (V != 0), c_max (V = 0),
clamped to [c_min, c_max], with F0's sign function smoothed over 5 mm/s.
It is a stand-in with a physically sensible shape, not a model of measured
data: `dampnet train` produces those, and `dampnet.export.write_header`
writes their headers in exactly this format.

Run: python export/make_default_model.py [--force]
"""

import argparse
from pathlib import Path

import numpy as np

from dampnet.export import write_header
from dampnet.model import MlpModel, mapminmax_settings

C_MIN, C_MAX, GAMMA, F0 = 1500.0, 9000.0, 4000.0, 60.0  # N s/m, N s/m, N s/(m V), N
V_RANGE, A_RANGE, U_RANGE = 0.48, 9.0, 5.0  # 1 inch at 3 Hz: |v| <= 0.48 m/s, |a| <= 9 m/s^2


def parametric_force(v, u):
    c = np.where(u > 0, GAMMA / np.maximum(u, 1e-9) + C_MIN, C_MAX)
    return np.clip(c, C_MIN, C_MAX) * v + F0 * np.tanh(v / 0.005)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--force", action="store_true", help="overwrite the existing header")
    args = ap.parse_args()
    rng = np.random.default_rng(2026)
    n = 20000
    x = np.column_stack([rng.uniform(-V_RANGE, V_RANGE, n), rng.uniform(-A_RANGE, A_RANGE, n),
                         rng.uniform(0, U_RANGE, n)])
    y = parametric_force(x[:, 0], x[:, 2])
    in_off, in_gain = mapminmax_settings(x)
    (out_off,), (out_gain,) = mapminmax_settings(y[:, None])
    xs = (x - in_off) * in_gain - 1.0
    ys = (y - out_off) * out_gain - 1.0
    w1 = rng.normal(0.0, 2.0, (30, 3))
    b1 = rng.normal(0.0, 1.0, 30)
    h = np.tanh(xs @ w1.T + b1)
    design = np.column_stack([h, np.ones(n)])
    coef, *_ = np.linalg.lstsq(design, ys, rcond=None)
    model = MlpModel(w1=w1, b1=b1, w_out=coef[:30], b_out=coef[30], in_offset=in_off,
                     in_gain=in_gain, out_offset=out_off, out_gain=out_gain,
                     sat_lo=x.min(axis=0), sat_hi=x.max(axis=0),
                     features=["velocity", "acceleration", "voltage"], units=["m/s", "m/s^2", "V"],
                     activation="tanh",
                     meta={"algorithm": "least squares on the output layer (stand-in model)",
                           "data": "thesis eq. 1-3 parametric damper, 20000 random samples",
                           "exported_at": "2026-11-21T00:00:00Z"})
    rms = float(np.sqrt(np.mean((design @ coef - ys) ** 2)) / out_gain)
    here = Path(__file__).resolve().parent
    write_header(model, here / "dn_model_default.h", prefix="dn_model_default", overwrite=args.force)
    model.save(here / "dn_model_default.json", overwrite=args.force)
    print(f"wrote {here}/dn_model_default.{{h,json}} (fit RMS error {rms:.1f} N over a "
          f"{2 / out_gain:.0f} N range)")


if __name__ == "__main__":
    main()
