"""`dampnet train DATA --out MODEL_DIR`: train an MLP damper model (thesis chapter 4).

Writes MODEL_DIR/model.json, metrics.json and model.h (the C header) atomically.
The pipeline is `dampnet.training.pipeline.train_dataset`; see its docstring for the steps.
"""

from __future__ import annotations

import argparse
import sys
import time

from dampnet.commands.common import DATA_HELP, add_channel_map_option, add_data_fix_options, apply_data_fixes, error, load_all
from dampnet.commands.training_options import ADD_RULE, Progress, add_training_options, training_request, whole


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `train` subcommand; its handler is `run`."""
    from dampnet.training.settings import OPTIONS

    p = subparsers.add_parser(
        "train", help="train an MLP damper model from dyno data",
        description="Train the thesis's MLP (velocity, acceleration, control -> force) on a dataset, "
                    f"hold out the {OPTIONS['holdout_voltage'].default:g} V tests for evaluation, and write MODEL_DIR with model.json, "
                    "metrics.json and the C header model.h. --add EFFECT adds what captures a physical "
                    f"effect the diagnosis named: {ADD_RULE}, e.g. `dampnet diagnose MODEL DATA --json d.json` "
                    "then `dampnet train DATA --out MODEL2 --add valve_lag --diagnosis d.json`.")
    p.add_argument("data", nargs="+", metavar="DATA",
                   help=f"dataset: {DATA_HELP} (see dampnet rig); several are trained on "
                        "as one (e.g. a campaign and the tests dampnet plan-tests proposed; test ids must be unique)")
    p.add_argument("--out", required=True, help="model directory to write (must not exist unless --force)")
    add_channel_map_option(p)
    add_training_options(p, train=True)
    p.add_argument("--prefix", default="dn_model", help="C identifier prefix in model.h (default dn_model)")
    add_data_fix_options(p)
    p.add_argument("--force", action="store_true", help="replace MODEL_DIR if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary (for scripts)")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Train and write MODEL_DIR; 0 on success, 2 (one-line message) on bad input.
    The request and the training are dampnet.recipes.training's (as the sweep's and dampnet.train)."""
    from pathlib import Path

    from dampnet.data import DataError
    from dampnet.model import ModelError
    from dampnet.outputs import check_output_dir
    from dampnet.recipes.training import plan

    out = Path(args.out)
    inputs = [*args.data, *([args.diagnosis] if args.diagnosis else []), *([args.channel_map] if args.channel_map else [])]
    bar = None
    try:
        check_output_dir(out, "model", inputs, args.force)  # before the work, again when writing
        req = training_request(args)
        req = req.check()  # every option and setting before the data are loaded, once
        workers = check_workers(args)
        ds = apply_data_fixes(load_all(args.data, args.channel_map), args)
        todo = plan(ds, req, check=False)  # checked above
        if todo.restarts > 1:
            bar = RestartProgress(not args.quiet)
        else:
            # valve "auto" trains twice (dampnet.training.valve_choice): the bar counts both
            bar = Progress(req.max_epochs * (2 if req.valve == "auto" else 1), f"train {todo.algorithm}",
                           not args.quiet)
        t0 = time.perf_counter()
        trained = todo.run(progress=bar, workers=workers)
        bar.close()
        t_train = time.perf_counter() - t0
        trained.save(out, force=args.force, prefix=args.prefix, inputs=inputs)
    except (DataError, ModelError, FileExistsError, ValueError, OSError) as e:
        if bar is not None:
            bar.close()
        return error(str(e))
    if not args.quiet:
        for a in trained.added:
            print(f"added {a['effect']}: features {', '.join(a['features'])}"
                  + "".join(f", {k} = {v:.4g}" for k, v in a["feature_params"].items())
                  + f" (parameters: {a['parameters_from']})")
        print_summary(trained.model, trained.info, trained.split, trained.metrics, out, t_train)
        if trained.algorithm_note:
            print(f"algorithm: {trained.model.meta.get('algorithm')} ({trained.algorithm_note})")
        if trained.restarts_note:
            print(f"restarts: {trained.restarts} ({trained.restarts_note})")
        if trained.valve_note:
            print(trained.valve_note)
    return 0


def check_workers(args) -> int | None:
    """--workers as a whole number in its range (None when not given)."""
    from dampnet.training.settings import option

    return option("workers", None if args.workers is None else whole(args.workers, "workers"))


class RestartProgress(Progress):
    """A tqdm bar over the restarts' fits (each runs whole in a worker process)."""

    def __init__(self, enabled: bool):
        super().__init__(0, "train restarts", enabled)

    def __call__(self, rec: dict):
        if self.enabled and self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=rec["total"], desc=self.desc, unit="fit", file=sys.stderr, leave=False)
        if self.bar is not None:
            if "score" in rec:
                self.bar.set_postfix({"restart": rec["restart"], "score": f"{rec['score']:.4f}"}, refresh=False)
            self.bar.update(1)
        return None


def structure_line(model, st: dict) -> str:
    """One line of metrics.json's "structure" and the priors (dampnet.evaluation.structure)."""
    parts = []
    if "velocity_falling_share" in st:
        falling = st["velocity_falling_share"]
        hint = ""
        if falling > 0 and not model.meta.get("monotone_prior", {}).get("weight"):
            from dampnet.training.monotone_prior import RECOMMENDED_WEIGHT

            hint = f" (--monotone-prior {RECOMMENDED_WEIGHT:g} asks it to rise)"
        parts.append(f"force falls with velocity at {100 * falling:.1f} % of the training samples{hint}")
    if "control_bend_nrmse" in st:
        parts.append(f"half-way between adjacent control levels {100 * st['control_bend_nrmse']:.1f} % of the force "
                     f"range (RMS) off their straight line, outside both levels' forces at "
                     f"{100 * st['control_reversal_share']:.1f} %")
    for key, name in (("control_prior", "control prior"), ("monotone_prior", "monotone prior")):
        prior = model.meta.get(key, {})
        if prior.get("weight"):
            parts.append(f"{name} {prior['weight']:g}" + (f" (off: {prior['off']})" if "off" in prior else ""))
    return ("structure: " + "; ".join(parts)) if parts else ""


def bandwidth_text(bandwidths_hz: list[float]) -> str:
    """The acceleration's bandwidths [Hz] over the tests in words: '40', or '4.2 to 40'."""
    lo, hi = min(bandwidths_hz), max(bandwidths_hz)
    return f"{lo:g}" if lo == hi else f"{lo:.3g} to {hi:.3g}"


def print_summary(model, info, split, metrics, out, t_train) -> None:
    from dampnet.evaluation.metrics import format_table

    net = f"{model.n_inputs}-{'-'.join(map(str, model.hidden))}-1"
    print(f"{out}: {net} MLP ({', '.join(model.features)}), {info.algorithm}, {info.epochs} epochs "
          f"({info.stop_reason}) in {info.time_s:.1f} s ({t_train:.1f} s with data preparation)")
    if model.terms:
        print("physics terms: " + "; ".join(f"{t['kind']} {t['params']}" for t in model.terms))
    vd = model.meta.get("data", {}).get("velocity_derived")
    if vd:
        print(f"velocity derived from displacement in {len(vd['tests'])} tests: {vd['method']}, bandwidth "
              f"{', '.join(f'{b:g}' for b in vd['bandwidth_hz'])} Hz, "
              f"{', '.join(f'{c:g}' for c in vd['edge_cut_s'])} s cut at each end")
    acc = model.meta.get("data", {}).get("acceleration")
    if acc:
        print("acceleration derived: " + acc["method"]
              + (f", bandwidth {bandwidth_text(acc['bandwidth_hz'])} Hz" if "bandwidth_hz" in acc
                 else f", window {acc['window']} s"))
    m = info.metrics
    if set(m) == {"all"}:  # an average of restarts (--average): no rows held out of every member
        print(f"NRMSE on all training samples {m['all']:.4f} (the averaged network; its members split the samples "
              f"differently, so it has no validation or test rows of its own; decimated by {split.decimate})")
    else:
        print(f"NRMSE train {m.get('train', float('nan')):.4f}, validation {m.get('val', float('nan')):.4f}, "
              f"test {m.get('test', float('nan')):.4f} ({info.n_train} training samples, decimated by "
              f"{split.decimate})")
    rest = model.meta.get("rest_force")
    if rest and info.n_rest_points:
        found = (f"{rest['force_N']:.1f} N on average, estimated from {rest['rows']:,} training samples near v = 0"
                 if rest["source"] == "estimated" else rest["source"])
        print(f"rest points: {info.n_rest_points:,} at {rest.get('target_N', 0.0):.1f} N "
              + ("(the thesis's 0 N; " if rest.get("target") == "zero" else "(")
              + f"the damper's own force at rest: {found})")
    if "holdout" in metrics:
        print(format_table(metrics["holdout"], f"hold-out tests ({len(split.holdout_ids)}):"))
        lk = metrics.get("holdout_lookup", {})
        if "overall" in lk:
            print(f"lookup-table baseline on the hold-out: NRMSE {lk['overall']['nrmse']:.4f}")
        if "holdout_regions" in metrics:
            from dampnet.evaluation.regions import summary_lines

            for line in summary_lines(metrics["holdout_regions"]):
                print(f"hold-out {line}")
    line = structure_line(model, metrics.get("structure", {}))
    if line:
        print(line)
    if "restarts" in metrics["training"]:
        from dampnet.training.restarts import summary_line

        print(summary_line(metrics["training"]["restarts"]))
    if "noise_floor" in metrics:
        print(f"noise floor of these data (rig sensor noise): NRMSE {metrics['noise_floor']['nrmse_range']:.4f}")
        hv = metrics["noise_floor"].get("holdout_vs_floor")
        if hv:
            print(f"hold-out error {hv['ratio']:.1f}x the noise floor (per frequency: "
                  + ", ".join(f"{r['frequency_hz']:g} Hz {r['ratio']:.1f}x" for r in hv["per_frequency"]
                              if r["frequency_hz"] is not None) + ")")
