"""The cold inverse's first-iterate grid (damper.hpp InverseGuess): how its size sets the
evaluations a call (issue 55 item 4). The grid's first iterate copied into numpy (the force over
velocity x control at a = 0 with dF/da there, interpolated in v, moved linearly in a, the crossing
cell's line), then the runtime's Halley steps from it (Damper.inverse(u_start=...)), on the bench's
case: the default model in float, v and a uniform over the model's range, the demand uniform
between the limits' forces, 2 x 10^4 calls. The runtime's own grid (33 x 17) is the cold call's
row; the table's others are what another capacity would give.

    python bench/experiments/inverse_grid.py      # ~1 min
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests" / "python"))
from test_damper_inverse import default_model, motion  # noqa: E402

from dampnet.sim.quarter_car.loop import damper_from_model  # noqa: E402

SIZES = [(33, 9), (17, 17), (33, 17), (33, 25), (65, 17), (65, 33)]


def grid(d, v_rng, nv, nu, lo, hi, h=0.5):
    vg, ug = np.linspace(*v_rng, nv), np.linspace(lo, hi, nu)
    V, U = np.meshgrid(vg, ug, indexing="ij")
    k = V.size
    base = dict(x=np.zeros(k), v=V.ravel(), u_lag=np.zeros(k), temperature=np.full(k, 20.0), u=U.ravel())
    f0 = d.forces(a=np.zeros(k), **base)[0].reshape(V.shape)
    fa = (d.forces(a=np.full(k, h), **base)[0] - d.forces(a=np.full(k, -h), **base)[0]).reshape(V.shape) / (2 * h)
    return vg, ug, f0, fa


def guess(g, v, a, f):
    vg, ug, f0, fa = g
    t = np.clip((v - vg[0]) / (vg[1] - vg[0]), 0, len(vg) - 1 - 1e-9)
    i = np.floor(t).astype(int)
    w = (t - i)[:, None]
    rows = (f0[i] + a[:, None] * fa[i]) * (1 - w) + (f0[i + 1] + a[:, None] * fa[i + 1]) * w - f[:, None]
    out = np.empty(len(v))
    for r, s in enumerate(rows):
        ks = np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))
        if len(ks) == 0:
            out[r] = ug[0] if abs(s[0]) <= abs(s[-1]) else ug[-1]
        else:
            k = ks[0]
            out[r] = ug[k] + (ug[k + 1] - ug[k]) * s[k] / (s[k] - s[k + 1])
    return out


def main() -> int:
    m = default_model()
    d = damper_from_model(m, single=True)
    lo, hi = d.control_range()
    iv, ia = m.features.index("velocity"), m.features.index("acceleration")
    rng = np.random.default_rng(1)
    n = 20_000
    inp = {"x": np.zeros(n), "u_lag": np.zeros(n), "temperature": np.full(n, 20.0),
           "v": rng.uniform(m.sat_lo[iv], m.sat_hi[iv], n), "a": rng.uniform(m.sat_lo[ia], m.sat_hi[ia], n)}
    f_lo, f_hi = (d.forces(**motion(inp), u=u)[0] for u in (lo, hi))
    dem = f_lo + (f_hi - f_lo) * rng.uniform(0, 1, n)
    ev_cold = d.inverse(dem, **motion(inp))[3]
    print(f"the runtime's cold call (its grid, 33 x 17): {ev_cold.mean():.2f} evaluations a call, "
          f"{np.mean(ev_cold == 2):.0%} in two")
    for nv, nu in SIZES:
        g = grid(d, (m.sat_lo[iv], m.sat_hi[iv]), nv, nu, lo, hi)
        ev = d.inverse(dem, **motion(inp), u_start=guess(g, inp["v"], inp["a"], dem))[3]
        print(f"{nv:3d} x {nu:2d} ({2 * nv * nu * 4 / 1024:.1f} KB float): {ev.mean():.2f} evaluations a call, "
              f"{np.mean(ev == 2):.0%} in two")
    return 0


if __name__ == "__main__":
    sys.exit(main())
