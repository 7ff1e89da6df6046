"""How far a float damper's force jitters in the control, against the inverse's stopping rule
(issue 55 item 4; cpp/include/dampnet/damper.hpp, search(): a float damper stops once |F - demand|
is within a float epsilon of |b_out| + sum |w_out|, Mlp::out_bound).

The default model as a float and as a double damper (dampnet.sim.quarter_car.loop.damper_from_model),
F on 401 controls 1e-6 V apart at a few motions: the float force less the double one, less its
quadratic trend, is the float kernel's rounding. Printed: its sd and largest value at each motion,
8 float epsilons of the force there (the rule before), and the rule's bound now. Then the bench's
controller trajectory (bench/bench_mlp.cpp damper_inverse_near_float_chained: 1 kHz, velocity
0.25 m/s at 1.46 Hz + 0.05 m/s at 11 Hz, the demand the force at a control sweeping 90 % of the
range at 0.73 Hz): the median and 90th percentile of the demand's change from one step to the next.

    python bench/experiments/float_force_jitter.py      # a few seconds
"""

import numpy as np

from dampnet.modeldir import default_model
from dampnet.sim.quarter_car.loop import damper_from_model

EPS_F = float(np.finfo(np.float32).eps)


def main() -> None:
    model = default_model()
    df, dd = damper_from_model(model, single=True), damper_from_model(model, single=False)
    bound = EPS_F * (abs(model.b_out) + np.sum(np.abs(model.w_out))) / model.out_gain
    print(f"the rule's bound: eps_float (|b_out| + sum |w_out|) = {bound:.2e} N")
    for v, a, u0 in ((0.111, 2.0, 2.8), (0.171, 1.0, 3.39), (0.3, -3.0, 1.0), (-0.2, 4.0, 4.0), (0.01, 0.5, 2.5)):
        u = u0 + np.arange(-200, 201) * 1e-6
        mo = dict(x=0.0, v=v, a=a, u_lag=0.0, temperature=20.0)
        f32, f64 = df.forces(u=u, **mo)[0], dd.forces(u=u, **mo)[0]
        err = f32 - f64
        jit = err - np.polyval(np.polyfit(u - u0, err, 2), u - u0)
        print(f"v {v:+.3f} m/s, a {a:+.1f} m/s^2, F {f64[200]:8.1f} N: jitter sd {np.std(jit):.1e} N, "
              f"largest {np.abs(jit).max():.1e} N; 8 eps |F| = {8 * EPS_F * abs(f64[200]):.1e} N")
    lo, hi = dd.control_range()
    period, t = 4.096, np.arange(4096) * 1e-3
    w1, w2, w3 = (2 * np.pi * k / period for k in (6, 45, 3))
    v = 0.25 * np.sin(w1 * t) + 0.05 * np.sin(w2 * t)
    acc = 0.25 * w1 * np.cos(w1 * t) + 0.05 * w2 * np.cos(w2 * t)
    u = lo + (hi - lo) * (0.5 + 0.45 * np.sin(w3 * t))
    demand = df.forces(x=0.0, v=v, a=acc, u=u, u_lag=0.0, temperature=20.0)[0]
    step = np.abs(np.diff(demand))
    print(f"the bench trajectory: the demand moves {np.median(step):.2f} N a step (median), "
          f"{np.percentile(step, 90):.2f} N (90th percentile)")


if __name__ == "__main__":
    main()
