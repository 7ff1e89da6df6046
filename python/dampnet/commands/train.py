"""`dampnet train DATA --out MODEL_DIR`: train an MLP damper model (thesis chapter 4).

Writes MODEL_DIR/model.json, metrics.json and model.h (the C header) atomically.
The pipeline is `dampnet.training.pipeline.train_dataset`; see its docstring for the steps.
"""

from __future__ import annotations

import argparse
import sys
import time

from dampnet.commands.common import error
from dampnet.commands.training_options import (
    ADD_RULE,
    Progress,
    add_effects,
    add_training_options,
    option_kwargs,
)


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `train` subcommand; its handler is `run`."""
    p = subparsers.add_parser(
        "train", help="train an MLP damper model from dyno data",
        description="Train the thesis's MLP (velocity, acceleration, control -> force) on a dataset, "
                    "hold out the 2.25 V tests for evaluation, and write MODEL_DIR with model.json, "
                    "metrics.json and the C header model.h. --add EFFECT adds what captures a physical "
                    f"effect the diagnosis named: {ADD_RULE}, e.g. `dampnet diagnose MODEL DATA --json d.json` "
                    "then `dampnet train DATA --out MODEL2 --add valve_lag --diagnosis d.json`.")
    p.add_argument("data", nargs="+", metavar="DATA",
                   help="dataset: a directory, CSV/text file or .mat file (see dampnet rig); several are trained on "
                        "as one (e.g. a campaign and the tests dampnet plan-tests proposed; test ids must be unique)")
    p.add_argument("--out", required=True, help="model directory to write (must not exist unless --force)")
    add_training_options(p)
    p.add_argument("--restarts", default="auto", metavar="N",
                   help="train N times from different seeds (--seed first) and keep the model that interpolates "
                        "best between the training control levels, never looking at the hold-out (default "
                        "'auto': 6 when the training tests have two control levels or more, else 1; 1: train "
                        "once, exactly as before). model.json records every restart (meta.restarts)")
    p.add_argument("--restart-score", default="interpolation", choices=["interpolation", "lolo"],
                   help="how restarts are ranked: interpolation (default: how far each model strays between "
                        "adjacent levels from the smooth curve through its own predictions at them) or lolo "
                        "(leave-one-level-out refits on interior levels; costs about 2x more and selects worse, "
                        "bench/RESULTS.md)")
    p.add_argument("--average", type=int, default=1, metavar="K",
                   help="keep the K best restarts and average them into one network K times as wide (their mean "
                        "output, exactly; the width must fit the runtime's 64 neurons, e.g. 2 x 30 hidden): lower "
                        "held-out error than one seed or one wide network (bench/RESULTS.md 'Inside the "
                        "envelope'); default 1, the best restart alone")
    p.add_argument("--workers", default=None, metavar="N",
                   help="processes the restarts run in, one torch thread each (default: the local cores)")
    p.add_argument("--prefix", default="dn_model", help="C identifier prefix in model.h (default dn_model)")
    p.add_argument("--force", action="store_true", help="replace MODEL_DIR if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary (for scripts)")
    p.set_defaults(handler=run)
    return p


def run(args) -> int:
    """Train and write MODEL_DIR; 0 on success, 2 (one-line message) on bad input."""
    from pathlib import Path

    from dampnet.data import DataError, load_dataset, merge_datasets
    from dampnet.model import ModelError
    from dampnet.modeldir import save_model_dir
    from dampnet.outputs import check_output_dir
    from dampnet.training.pipeline import model_metrics

    out = Path(args.out)
    inputs = [*args.data, *([args.diagnosis] if args.diagnosis else [])]
    bar = None
    try:
        check_output_dir(out, "model", inputs, args.force)  # before the work, again when writing
        kw = option_kwargs(args)
        check_options(args, kw)  # every option and setting before the data are loaded
        ds = merge_datasets([load_dataset(d) for d in args.data])
        kw, added = add_effects(args, ds, kw)
        restarts, workers, note = restart_options(args, ds, kw)
        if restarts > 1:
            bar = RestartProgress(not args.quiet)
        else:
            bar = Progress(kw["max_epochs"], f"train {args.algorithm}", not args.quiet)
        from dampnet.training.pipeline import train_dataset

        t0 = time.perf_counter()
        model, info, split = train_dataset(ds, algorithm=args.algorithm, progress=bar, restarts=restarts,
                                           workers=workers, restart_score=args.restart_score,
                                           average=args.average, **kw)
        bar.close()
        t_train = time.perf_counter() - t0
        metrics = model_metrics(model, info, split)
        from dampnet.envelope import envelope_of

        save_model_dir(model, metrics, out, force=args.force, prefix=args.prefix, inputs=inputs,
                       envelope=envelope_of(model, split))
    except (DataError, ModelError, FileExistsError, ValueError, OSError) as e:
        if bar is not None:
            bar.close()
        return error(str(e))
    if not args.quiet:
        for a in added:
            print(f"added {a['effect']}: features {', '.join(a['features'])}"
                  + "".join(f", {k} = {v:.4g}" for k, v in a["feature_params"].items())
                  + f" (parameters: {a['parameters_from']})")
        print_summary(model, info, split, metrics, out, t_train)
        if note:
            print(f"restarts: 1 ({note})")
    return 0


def check_options(args, kw) -> None:
    """The training layer's checks (dampnet.training.settings; train_dataset repeats them) of every
    option and --settings, before any data are loaded: ValueError of one line naming the option."""
    from dampnet.training.restarts import check_average, check_restarts
    from dampnet.training.settings import check_request, train_settings

    check_request(algorithm=args.algorithm, settings=train_settings(args.algorithm, kw["settings"]),
                  hidden=kw["hidden"], features=kw["features"], max_epochs=kw["max_epochs"], seed=kw["seed"],
                  decimate=kw["decimate"], holdout_voltage=kw["holdout_voltage"])
    restarts, workers = given_restarts(args)
    check_restarts(1 if restarts is None else restarts, workers, args.restart_score)
    # with --restarts auto the count is known with the data: its relation to --average is checked then
    check_average(args.average, args.average if restarts is None else restarts, kw["hidden"], args.restart_score)


def given_restarts(args) -> tuple[int | None, int | None]:
    """(--restarts, None for 'auto'; --workers, None when not given) as whole numbers; their ranges are
    check_restarts's. ValueError (exit 2, one line) for anything else."""

    def whole(text: str, name: str) -> int:
        try:
            return int(str(text).strip())
        except ValueError:
            raise ValueError(f"--{name}: expected a whole number{' or auto' if name == 'restarts' else ''}, "
                             f"got {text!r}") from None

    workers = None if args.workers is None else whole(args.workers, "workers")
    if str(args.restarts).strip().lower() == "auto":
        return None, workers
    return whole(args.restarts, "restarts"), workers


def restart_options(args, ds, kw) -> tuple[int, int | None, str | None]:
    """(restarts, workers, why 'auto' trained once or None) from --restarts and --workers."""
    from dampnet.training.restarts import auto_restarts

    restarts, workers = given_restarts(args)
    if restarts is None:
        n, note = auto_restarts(ds, kw["holdout_voltage"], kw["holdout_tests"], kw["features"], args.restart_score)
        return n, workers, note
    return restarts, workers, None


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


def print_summary(model, info, split, metrics, out, t_train) -> None:
    from dampnet.evaluation.metrics import format_table

    net = f"{model.n_inputs}-{'-'.join(map(str, model.hidden))}-1"
    print(f"{out}: {net} MLP ({', '.join(model.features)}), {info.algorithm}, {info.epochs} epochs "
          f"({info.stop_reason}) in {info.time_s:.1f} s ({t_train:.1f} s with data preparation)")
    if model.terms:
        print("physics terms: " + "; ".join(f"{t['kind']} {t['params']}" for t in model.terms))
    m = info.metrics
    if set(m) == {"all"}:  # an average of restarts (--average): no rows held out of every member
        print(f"NRMSE on all training samples {m['all']:.4f} (the averaged network; its members split the samples "
              f"differently, so it has no validation or test rows of its own; decimated by {split.decimate})")
    else:
        print(f"NRMSE train {m.get('train', float('nan')):.4f}, validation {m.get('val', float('nan')):.4f}, "
              f"test {m.get('test', float('nan')):.4f} ({info.n_train} training samples, decimated by "
              f"{split.decimate})")
    if "holdout" in metrics:
        print(format_table(metrics["holdout"], f"hold-out tests ({len(split.holdout_ids)}):"))
        lk = metrics.get("holdout_lookup", {})
        if "overall" in lk:
            print(f"lookup-table baseline on the hold-out: NRMSE {lk['overall']['nrmse']:.4f}")
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
