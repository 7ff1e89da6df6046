"""dampnet from Python: load the default model, evaluate it on a small virtual-rig dataset,
diagnose what it misses, and run it in the quarter-car loop.

The loop is the configuration of examples/c/quarter_car.c and examples/cpp/quarter_car.cpp
(default neural damper, on-off skyhook with a 5 ms command filter, Table 5 vehicle, RK4 at
1 ms, the two-tone road, 3000 steps) and prints the same "result" line (SI units: t [s],
z [m], v [m/s], acc_s_rms [m/s^2], force_max [N]; saturated / unconverged: steps with
those warnings). tests/python/test_examples.py checks that the three agree.

    python examples/python/quarter_car.py [MODEL]     # MODEL: model.json or a model directory
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import dampnet
from dampnet import _core

N_STEPS = 3000
DT_S = 0.001
DEFAULT_MODEL = Path(__file__).resolve().parents[2] / "export" / "dn_model_default.json"


def two_tone_road(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The examples' road [m] and its rate [m/s]: 3 cm peak to peak at 1.2 Hz plus 6 mm at
    6 Hz, raised cosines starting at rest."""
    a1, w1, a2, w2 = 0.015, 2 * np.pi * 1.2, 0.002, 2 * np.pi * 6.0
    z = a1 * (1 - np.cos(w1 * t)) + a2 * (1 - np.cos(w2 * t))
    rate = a1 * w1 * np.sin(w1 * t) + a2 * w2 * np.sin(w2 * t)
    return z, rate


def main(model_path: Path) -> None:
    model = dampnet.load_model(model_path)
    print(f"model {model.model_id()}: {'-'.join(map(str, (model.n_inputs, *model.hidden, 1)))} "
          f"on {', '.join(model.features)}")

    # A small dataset from the virtual dyno (9 tests), with a gas spring the model never saw.
    data = dampnet.rig.generate("quick", effects=["gas_spring"], seed=0)
    errors = dampnet.evaluate(model, data)
    print(f"evaluate: NRMSE {errors['overall']['nrmse']:.4f} over {errors['overall']['n_tests']} "
          f"rig tests (RMSE {errors['overall']['rmse_n']:.1f} N)")
    diagnosis = dampnet.diagnose(model, data)
    print(f"diagnose: missing effect {diagnosis['verdict']!r}")

    # The quarter-car loop in C++ (GIL released): road samples at t = 0, dt, ..., N dt give
    # N steps; row k holds the state at t_k and the report of the step from t_k.
    car = dampnet.QuarterCar(dampnet.damper_from_model(model),
                             controller={"kind": "skyhook_onoff", "u_tau_s": 0.005})
    z, rate = two_tone_road(np.arange(N_STEPS + 1) * DT_S)
    run = car.simulate(z, rate)
    final = dict(zip(_core.STATE_NAMES, run["state"][-1]))
    steps = slice(0, N_STEPS)  # the last row is a report without a step
    status = run["status"][steps]
    print(f"dampnet {dampnet.__version__}, Python: default model, skyhook on-off, {N_STEPS} steps "
          f"of {DT_S:g} s")
    print(f"result t={final['t']:.12g} z_s={final['z_s']:.12g} v_s={final['v_s']:.12g} "
          f"z_us={final['z_us']:.12g} v_us={final['v_us']:.12g} "
          f"acc_s_rms={np.sqrt(np.mean(run['acc_s'][steps] ** 2)):.12g} "
          f"force_max={np.max(np.abs(run['force'][steps])):.12g} "
          f"saturated={np.count_nonzero(status & _core.DN_W_SATURATED)} "
          f"unconverged={np.count_nonzero(status & _core.DN_W_ACCEL_UNCONVERGED)}")

    # The same car on the thesis's rough road at 20 m/s (a fresh loop state).
    road = dampnet.roads.thesis_rough_road(seed=0).sample(DT_S, speed=20.0)
    rough = car.spawn().simulate(road.z, road.zdot)
    print(f"thesis rough road at 20 m/s: sprung acceleration RMS "
          f"{np.sqrt(np.mean(rough['acc_s'] ** 2)):.3f} m/s^2 over {road.t[-1]:.1f} s")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT_MODEL)
