"""`dampnet study MODEL [DATA]`: the thesis's chapter 5 quarter-car study (Tables 6 and 7, skyhook)."""

from __future__ import annotations

import argparse
import sys

from dampnet.outputs import json_text


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "study", help="reproduce the thesis's quarter-car study (Tables 6, 7, skyhook)",
        description="Impulse and sine sweep at low and high damping, rough road at 10 and 20 m/s, skyhook "
                    "against passive - for MODEL, the lookup-table model fitted to DATA and, when DATA "
                    "comes from the virtual rig, the truth damper (with each model's error against it).")
    p.add_argument("model", help="model directory or model.json")
    p.add_argument("data", nargs="?", default=None, help="dataset (for the lookup table and the truth)")
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=0, help="seed of the rough road")
    p.add_argument("--out", default="study_out", help="output directory (study.json, study.txt, PNGs)")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--quick", action="store_true",
                   help="shortened roads: a 5x faster sweep (0.5 octave/s) and half the rough road (92 m)")
    p.add_argument("--vehicle", action="store_true",
                   help="also the full vehicle (chapter 5.2): the bounce sine sweep and the ISO 3888-1 lane "
                        "change at 120 km/h, every model at low and high damping and under skyhook")
    p.add_argument("--force", action="store_true", help="replace an existing study in --out")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    from pathlib import Path

    from dampnet.data.types import RIG_GENERATOR
    from dampnet.outputs import check_run_dir
    from dampnet.sim.dampers import load_spec, lookup_spec, truth_spec
    from dampnet.sim.plots import write_plots
    from dampnet.sim.quarter_car.report import text_tables, without_arrays
    from dampnet.sim.quarter_car.study import INPUTS_FILE, neural_inputs, run_study

    out = Path(args.out)
    try:
        from dampnet.sim import limits

        limits.check_number("--dt", args.dt, limits.STEP_S)
        limits.check_seed("--seed", args.seed)
        check_run_dir(out, ("study.json", "study.txt", "inputs.npz"), "study.json", "dampnet.sim.quarter_car.study/",
                      [p for p in (args.model, args.data) if p and Path(p).exists()], args.force)
        from dampnet.sim.roads import sine_sweep, thesis_rough_road

        roads = ({"sweep": sine_sweep(rate_oct_s=0.5), "rough": thesis_rough_road(seed=args.seed, base_length_m=46.0)}
                 if args.quick else {})
        specs = [load_spec(args.model)]
        truth = None
        if args.data:
            from dampnet.data import load_dataset
            from dampnet.evaluation.lookup import fit_lookup

            ds = load_dataset(args.data)
            specs.append(lookup_spec(fit_lookup(ds)))
            if ds.meta.get("generator") == RIG_GENERATOR:
                truth = truth_spec(list(ds.meta.get("effects", {})))
        from dampnet.recipes import control_laws

        res = run_study(specs, truth, dt=args.dt, seed=args.seed, keep_runs=not args.no_plots, laws=control_laws.make,
                        progress=lambda s: print(f"  {s}", file=sys.stderr), **roads)
        vehicle = _vehicle_study(specs + ([truth] if truth else []), args) if args.vehicle else None
    except (ValueError, OSError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    from dampnet.outputs import staged_files

    table = text_tables(res)
    if vehicle is not None:
        from dampnet.sim.full_car.study import text_table

        table += "\n\nfull vehicle (chapter 5.2)\n" + text_table(vehicle)
    try:
        wrote_inputs = False
        with staged_files(out) as tmp:  # study.json (the marker) moved into place last
            data = without_arrays(res)
            if vehicle is not None:
                data["vehicle"] = {k: vehicle[k] for k in ("results", "errors", "coverage") if k in vehicle}
            (tmp / "study.json").write_text(json_text(data))
            (tmp / "study.txt").write_text(table + "\n")
            if not args.no_plots:
                write_plots(res, tmp)
                inputs = neural_inputs(res)  # for dampnet plan-tests STUDY_DIR
                if inputs:
                    import numpy as np

                    np.savez_compressed(tmp / INPUTS_FILE, **inputs)
                    wrote_inputs = True
        if not wrote_inputs and (out / INPUTS_FILE).is_file():
            (out / INPUTS_FILE).unlink()  # a replaced (--force) study's inputs are not this one's
    except OSError as e:
        print(f"dampnet: error: {out}: cannot write the study ({e.strerror or e})", file=sys.stderr)
        return 2
    print(table)
    for name, ex in res.get("extrapolated", {}).items():
        print(f"coverage of {name}: " + (f"extrapolated in {len(ex['extrapolated'])} of {ex['runs']} runs: the "
              f"model was outside its training data for {_worst_run(res, name)}" if ex["any"]
              else f"within its training data in all {ex['runs']} runs"))
    print(f"-> {out}/study.json, study.txt" + ("" if args.no_plots else ", PNG plots"))
    return 0


def _worst_run(res: dict, name: str) -> str:
    """The run of a study where model `name` spent the largest share of time outside its envelope,
    in words: "X % of <section case> (its verdict)"."""
    runs = [(by[name]["outside"]["share_time"], f"{section} {case}", by[name]["verdict"])
            for section, cases in res["coverage"].items() for case, by in cases.items() if name in by]
    share, where, verdict = max(runs)
    return f"{100 * share:.1f} % of {where}, the most ({verdict})"


def _vehicle_study(specs, args) -> dict:
    """The full-vehicle comparison (dampnet.sim.full_car.study) of the study's models: BSST (a 4x
    faster sweep with --quick) and the lane change, low / high damping and on-off skyhook."""
    from dampnet.recipes import maneuvers

    tests = {"bsst_heave": maneuvers.build("bsst", args.dt, {"bsst_rate_oct_s": 1.0 if args.quick else 0.25}),
             "dlc": maneuvers.build("dlc", args.dt)}
    return maneuvers.run_study(specs, tests, progress=lambda s: print(f"  vehicle {s}", file=sys.stderr))
