"""What the velocity channel's noise alone costs a perfect model on the rig (issue 54, the noise floor;
not a product feature).

The rig's thesis plan (rig seed 0), its held-out 2.25 V tests: the rig's static hydraulic law
(dampnet.rig.truth.hydraulic_force at the test's voltage and the reference temperature) at the
measured velocity against the same law at the velocity smoothed (Savitzky-Golay, 51 samples, cubic:
the tests are sines, far slower than the noise). The RMS difference is the force error a model
exact in velocity would make from the channel's noise; beside the load cell's (the rig's noise
floor, noise_floor_rmse_n) it gives the floor such a model would sit at.

    python bench/experiments/input_noise_floor.py

About 15 s.
"""

from __future__ import annotations

import numpy as np


def main() -> None:
    from scipy.signal import savgol_filter

    from dampnet.rig import generate, noise_floor_rmse_n
    from dampnet.rig.truth import TruthParams, controller_current, hydraulic_force, valve_opening

    p = TruthParams()
    ds = generate("thesis", seed=0)
    sq, n, noise = 0.0, 0, []
    for t in ds.tests:
        if abs(float(t.control_nominal) - 2.25) > 1e-9:
            continue
        v = t.channels["velocity"]
        smooth = savgol_filter(v, 51, 3)
        opening = valve_opening(controller_current(np.full(v.size, float(t.control_nominal)), p), p)
        d = hydraulic_force(v, opening, p.temperature_ref_c, p) - hydraulic_force(smooth, opening, p.temperature_ref_c, p)
        sq += float(np.sum(d ** 2))
        n += d.size
        noise.append(float(np.std(v - smooth)))
    rms, floor = np.sqrt(sq / n), noise_floor_rmse_n(ds)
    print(f"velocity noise (median over the tests): {1e3 * np.median(noise):.2f} mm/s")
    print(f"force error from it through the static law: {rms:.2f} N RMS; load cell floor {floor:.2f} N")
    print(f"a model exact in velocity: {np.hypot(rms, floor) / floor:.2f}x the floor")


if __name__ == "__main__":
    main()
