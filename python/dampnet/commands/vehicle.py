"""`dampnet vehicle MODEL --test bsst|dlc|road`: one full-vehicle test (the thesis's chapter 5.2)
with the damper model at all four corners, in the runtime's FullCar."""

from __future__ import annotations

import argparse
import sys

RUN_SCHEMA = "dampnet.vehicle/1"
#: the files of a run (metrics.json is its marker: a JSON object with "schema": RUN_SCHEMA)
RUN_FILES = ("run.npz", "metrics.json", "vehicle.png", "coverage.png")
TESTS = ("bsst", "dlc", "road")


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "vehicle", help="run a damper model in the full vehicle: bounce sweep, lane change, rough road",
        description="Run MODEL (a model directory or model.json, a lookup-table JSON, 'truth' or "
                    "'truth:EFFECT,...', or 'linear:C' [N s/m]) at all four corners of the full vehicle "
                    "(a compact pickup; see README) and write metrics.json, run.npz and vehicle.png. "
                    "Tests: bsst (bounce sine sweep 0.5-20 Hz on a four-post rig), dlc (ISO 3888-1 "
                    "double lane change driven by the preview driver), road (two correlated tracks of "
                    "a rough road).")
    p.add_argument("model")
    p.add_argument("--test", choices=TESTS, default="dlc", help="the test (default dlc)")
    p.add_argument("--mode", choices=("heave", "pitch"), default="heave",
                   help="bsst: all wheels in phase (heave) or the rear against the front (pitch)")
    p.add_argument("--speed", type=float, default=None, metavar="KMH",
                   help="speed [km/h] of dlc (default 120, the thesis's) and road (default 60)")
    p.add_argument("--profile", default="thesis", help="road: 'thesis' (the thesis's rough road) or an ISO "
                   "8608 class A..H")
    p.add_argument("--damping", choices=("low", "high", "skyhook"), default="low",
                   help="passive at the damper's low or high setting, or on-off skyhook at every corner")
    p.add_argument("--dt", type=float, default=1e-3, help="step [s]")
    p.add_argument("--seed", type=int, default=0, help="seed of the rough road")
    p.add_argument("--out", default="vehicle_out", help="output directory")
    p.add_argument("--force", action="store_true", help="replace an existing run in --out")
    p.set_defaults(handler=run)
    return p


def check_options(args) -> None:
    """Every numeric option within its range (dampnet.sim.limits), before anything runs."""
    from dampnet.sim import limits

    limits.check_number("--dt", args.dt, limits.STEP_S)
    if args.speed is not None:
        limits.check_number("--speed", args.speed, limits.SPEED_KMH)
    limits.check_seed("--seed", args.seed)


def _maneuver(args):
    from dampnet.sim.full_car import maneuvers
    from dampnet.sim.full_car.runs import DEFAULT_SPEED_KMH
    from dampnet.sim.roads import RoadError

    if args.speed is not None and args.test == "bsst":
        raise RoadError("--speed: the bounce sine sweep runs at rest on a four-post rig; drop --speed")
    speed = DEFAULT_SPEED_KMH.get(args.test) if args.speed is None else args.speed
    if args.test == "bsst":
        return maneuvers.bsst(args.dt, args.mode)
    if args.test == "dlc":
        return maneuvers.dlc(args.dt, speed)
    if args.profile != "thesis" and args.profile not in tuple("ABCDEFGH"):
        raise RoadError(f"--profile: expected 'thesis' or an ISO 8608 class A..H, got {args.profile!r}")
    return maneuvers.rough_road(args.dt, speed, args.profile, args.seed)


def run(args) -> int:
    import os
    from pathlib import Path

    import numpy as np

    from dampnet.sim.full_car.plots import plot_test
    from dampnet.sim.full_car.runs import run as run_test
    from dampnet.model import ModelError
    from dampnet.outputs import check_run_dir, json_text, staged_files
    from dampnet.sim.dampers import load_spec
    from dampnet.sim.roads import RoadError
    from dampnet.sim.vehicle import LoopError

    out = Path(args.out)
    try:
        check_options(args)
        inputs = [args.model] if os.path.exists(args.model) else []
        check_run_dir(out, RUN_FILES, "metrics.json", RUN_SCHEMA.split("/")[0] + "/", inputs, args.force)
        spec = load_spec(args.model)
        man = _maneuver(args)
        print(f"running {man.name} ({man.road.shape[0] * man.dt:.1f} s simulated, "
              f"{man.road.shape[0]} steps) with {spec.name}, {args.damping} damping ...", flush=True)
        res = run_test(spec, man, args.damping)
    except (RoadError, LoopError, ModelError, ValueError, OSError, KeyError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    meta = {"schema": RUN_SCHEMA, **{k: v for k, v in res.items() if k != "arrays"}}
    if "coverage" in res:   # a neural model: the verdict at the top (dampnet.envelope.coverage)
        meta["extrapolated"] = res["coverage"]["extrapolated"]
    title = f"{spec.name}, {args.damping} damping: {man.name}"
    try:
        with staged_files(out) as tmp:
            np.savez_compressed(tmp / "run.npz", **res["arrays"])
            plot_test(args.test, {spec.name: res}, tmp / "vehicle.png", title)
            if "coverage" in res:
                from dampnet.envelope.coverage import fullcar_inputs
                from dampnet.envelope.plot import plot_coverage

                per = fullcar_inputs(spec.obj, res["arrays"])
                plot_coverage(spec.obj, {f"{spec.name} {c}": X for c, X in zip(("FL", "FR", "RL", "RR"), per)},
                              tmp / "coverage.png", spec.meta.get("envelope"), f"{title}: damper inputs")
            elif (out / "coverage.png").exists():   # --force over a neural model's run: not this run's
                (out / "coverage.png").unlink()
            (tmp / "metrics.json").write_text(json_text(meta))
    except OSError as e:
        print(f"dampnet: error: {out}: cannot write the run ({e.strerror or e})", file=sys.stderr)
        return 2
    m = res["metrics"]
    if args.test == "dlc":
        line = (f"a_y peak {m['a_y_peak_m_s2']:.2f} m/s^2, roll peak {m['roll_peak_deg']:.2f} deg, roll rate peak "
                f"{m['roll_rate_peak_deg_s']:.1f} deg/s, yaw rate peak {m['yaw_rate_peak_deg_s']:.1f} deg/s, "
                f"side-slip peak {m['side_slip_peak_deg']:.2f} deg, cones hit {m['cones_hit']} of {m['cones']} "
                f"({'passed' if m['passed'] else 'failed'})")
    elif args.test == "bsst":
        line = f"body acc RMS {m['acc_rms_m_s2']:.4f} m/s^2, peak {m['acc_peak_m_s2']:.3f} m/s^2"
    else:
        line = (f"body acc RMS {m['acc_rms_m_s2']:.4f} m/s^2, Wk RMS {m['acc_wk_rms_m_s2']:.4f} m/s^2, "
                f"roll rate RMS {m['roll_rate_rms_deg_s']:.2f} deg/s")
    print(f"{title}: {line} -> {out}")
    if "coverage" in res:
        from dampnet.envelope.coverage import summary_line

        print(summary_line(spec.name, res["coverage"]) + " (the four corners together)")
    return 0
