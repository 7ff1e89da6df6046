"""`dampnet simulate MODEL --road ... --speed ... --control ...`: one quarter-car run in the runtime's loop."""

from __future__ import annotations

import argparse
import sys

COMMAND_TAU_S = 0.005  # = dampnet.sim.calibration.SKYHOOK_COMMAND_TAU_S (not imported: keeps --help fast)


def control_laws() -> tuple[str, ...]:
    """The laws --control takes: the control-law registry's (dampnet.recipes.control_laws: the
    runtime's laws but "external", and passive_low / passive_high)."""
    from dampnet.recipes import control_laws as laws

    return laws.names()


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "simulate", help="run a damper model in the quarter-car loop over a road",
        description="Run MODEL (a model directory or model.json, 'default' for the embedded default model, "
                    "a lookup-table JSON, 'truth' or "
                    "'truth:EFFECT,...' for the rig's damper, or 'linear:C' [N s/m]) in the quarter-car "
                    "loop (thesis Table 5 vehicle) and write run.npz, metrics.json and PNG plots.")
    p.add_argument("model")
    p.add_argument("--road", default="rough",
                   help=f"a road: {_roads().usage()} (default rough, the thesis's; dampnet.recipes.roads)")
    p.add_argument("--speed", type=float, default=10.0, help="speed [m/s] for distance profiles")
    p.add_argument("--control", default="passive", metavar="LAW",
                   help=f"control law: {', '.join(control_laws())} (the runtime's names, and passive at one "
                        "level); each is calibrated on the damper as in `dampnet study` (dampnet.recipes.control_laws)")
    p.add_argument("--command-tau", type=float, default=None, metavar="S",
                   help="command filter time constant of the semi-active laws [s] (default: the study's "
                        f"{1e3 * COMMAND_TAU_S:g} ms for the switching and continuous laws, none for the "
                        "force-tracking ones; 0 = unfiltered)")
    p.add_argument("--damping", choices=("low", "high"), default=None,
                   help="passive control level (found from the model's control range; default high; "
                        "passive_low / passive_high name one)")
    p.add_argument("--u", type=float, default=None, help="passive control [V] (overrides --damping)")
    p.add_argument("--dt", type=float, default=1e-3, help="loop step [s]")
    p.add_argument("--seed", type=int, default=0, help="seed of random roads")
    p.add_argument("--out", default="simulate_out", help="output directory")
    p.add_argument("--force", action="store_true", help="replace an existing run in --out")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Check every option and the output, run (dampnet.recipes.quarter_car.run), write the run's
    directory (dampnet.sim.run_dir), print its summary; 0, or 2 with one line on bad input."""
    from dampnet.recipes import control_laws as laws
    from dampnet.recipes import quarter_car
    from dampnet.sim import run_dir
    from dampnet.sim.dampers import load_spec
    from dampnet.sim.roads import RoadError
    from dampnet.sim.vehicle import LoopError, Vehicle

    try:
        check_options(args)
        try:
            law = laws.get(args.control).name
        except LoopError as e:
            raise LoopError(f"--control: {e}") from None
        laws.check_context(args.control, {"--u": ("u", args.u), "--damping": ("damping", args.damping),
                                          "--command-tau": ("u_tau_s", args.command_tau)})
        run_dir.check(run_dir.QUARTER_CAR, args.out, _model_inputs(args.model, args.road), args.force)
        spec = load_spec(args.model)
        road = _roads().build(args.road, seed=args.seed, speed_m_s=args.speed)
        res = quarter_car.run(spec, road, args.control, speed_m_s=args.speed, vehicle=Vehicle(dt=args.dt),
                              u_tau_s=args.command_tau, damping=args.damping or "high", u=args.u)
    except (RoadError, LoopError, ValueError, OSError, KeyError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    try:
        run_dir.save_quarter_car(args.out, res, spec, road.name, law)
    except OSError as e:
        print(f"dampnet: error: {args.out}: cannot write the run ({e.strerror or e})", file=sys.stderr)
        return 2
    m, ctrl = res["metrics"], res["controller"]
    print(f"{spec.name} on {road.name}" + (f" at {args.speed:g} m/s" if road.kind == "spatial" else "")
          + f", {law}" + (f" (command filter {1e3 * ctrl['u_tau_s']:g} ms)"
                          if ctrl["kind"] != "passive" and ctrl["u_tau_s"] > 0 else "")
          + f" (dt {args.dt:g} s): acc RMS {m['acc_rms_m_s2']:.4f} m/s^2, "
          f"Wk RMS {m['acc_wk_rms_m_s2']:.4f} m/s^2, disp peak/RMS {m['disp_peak_to_rms']:.3f}, travel RMS "
          f"{1e3 * m['travel_rms_m']:.2f} mm (max {1e3 * m['travel_max_m']:.2f}), tyre load RMS "
          f"{m['tyre_load_rms_n']:.1f} N -> {args.out}")
    if "coverage" in res:
        from dampnet.envelope.coverage import summary_line

        print(summary_line(spec.name, res["coverage"]))
    return 0


def _roads():
    from dampnet.recipes import roads

    return roads


def check_options(args) -> None:
    """Every numeric option within its range (dampnet.sim.limits), before anything runs."""
    from dampnet.sim import limits

    limits.check_number("--dt", args.dt, limits.STEP_S)
    limits.check_number("--speed", args.speed, limits.SPEED_M_S)
    if args.command_tau is not None:
        limits.check_number("--command-tau (the controller's u_tau_s)", args.command_tau, limits.COMMAND_TAU_S)
    if args.u is not None:
        limits.check_number("--u", args.u, limits.CONTROL_V)
    limits.check_seed("--seed", args.seed)


def _model_inputs(model: str, road: str) -> list[str]:
    """The files this run reads (a model directory or file, a road CSV), for check_run_dir."""
    import os

    return [p for p in (model, road) if os.path.exists(p)]
