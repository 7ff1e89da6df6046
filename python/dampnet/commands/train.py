"""`dampnet train DATA --out MODEL_DIR`: train an MLP damper model (thesis chapter 4).

Writes MODEL_DIR/model.json, metrics.json and model.h (the C header) atomically.
The pipeline is `dampnet.training.pipeline.train_dataset`; see its docstring for the steps.
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register the `train` subcommand; its handler is `run`."""
    p = subparsers.add_parser(
        "train", help="train an MLP damper model from dyno data",
        description="Train the thesis's MLP (velocity, acceleration, control -> force) on a dataset, "
                    "hold out the 2.25 V tests for evaluation, and write MODEL_DIR with model.json, "
                    "metrics.json and the C header model.h.")
    p.add_argument("data", help="dataset: a directory, CSV/text file or .mat file (see dampnet rig)")
    p.add_argument("--out", required=True, help="model directory to write (must not exist unless --force)")
    add_training_options(p)
    p.add_argument("--prefix", default="dn_model", help="C identifier prefix in model.h (default dn_model)")
    p.add_argument("--force", action="store_true", help="replace MODEL_DIR if it exists")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no summary (for scripts)")
    p.set_defaults(handler=run)
    return p


def add_training_options(p: argparse.ArgumentParser, algorithm: bool = True) -> None:
    """Options shared by `train` and `compare-algorithms`."""
    from dampnet.training import ALGORITHMS

    p.add_argument("--features", default=None,
                   help="comma-separated input features in order (default: velocity,acceleration and "
                        "the data's control, voltage or current); e.g. velocity,acceleration,voltage,temperature")
    p.add_argument("--terms", default=None,
                   help='physics terms as JSON, e.g. \'[{"kind": "position_poly"}]\'; terms without '
                        '"params" are fitted by least squares, the MLP learns the rest')
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="add the features and terms that model a physical effect (repeatable; "
                        "effects from dampnet.diagnosis.catalogue)")
    if algorithm:
        p.add_argument("--algorithm", default="lm", choices=sorted(ALGORITHMS),
                       help="lm (Levenberg-Marquardt, default), br (Bayesian regularisation), "
                            "scg (scaled conjugate gradient), adam")
    p.add_argument("--hidden", default="30", help="hidden layer sizes, e.g. 30 or 20,10 (default 30)")
    p.add_argument("--activation", default="tanh", choices=["tanh", "sigmoid"],
                   help="hidden activation (default tanh, MATLAB's tansig)")
    p.add_argument("--holdout-voltage", default="2.25",
                   help="hold out every test at this nominal control value (default 2.25; 'none' for none)")
    p.add_argument("--holdout-tests", default="", help="comma-separated test ids to hold out as well")
    p.add_argument("--decimate", default="auto",
                   help="keep every N-th training sample ('auto': about 200 Hz, 25 at 5 kHz)")
    p.add_argument("--no-zero-points", action="store_true",
                   help="do not add the zero-input, zero-force training points")
    p.add_argument("--max-epochs", type=int, default=1000, help="epoch limit (default 1000)")
    p.add_argument("--seed", type=int, default=0, help="random seed (split, initial weights)")
    p.add_argument("--settings", default=None,
                   help='algorithm settings as JSON, e.g. \'{"mu_max": 1e8}\' or \'{"lr": 0.01}\'')


def error(msg: str) -> int:
    print(f"dampnet: error: {msg}", file=sys.stderr)
    return 2


def _json_arg(text: str | None, name: str, kind: type):
    if text is None:
        return None
    try:
        v = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"--{name}: not valid JSON ({e.msg} at column {e.colno})") from None
    if not isinstance(v, kind):
        raise ValueError(f"--{name}: expected a JSON {kind.__name__}")
    return v


def training_kwargs(args, ds) -> dict:
    """train_dataset keyword arguments from the parsed options (ValueError on bad ones)."""
    from dampnet.features import default_features

    features = [f.strip() for f in args.features.split(",") if f.strip()] if args.features else None
    terms = _json_arg(args.terms, "terms", list) or []
    for t in terms:
        if not isinstance(t, dict) or "kind" not in t:
            raise ValueError(f"--terms: each term must be an object with a 'kind', got {t!r}")
    feature_params: dict = {}
    for effect in args.add:
        add = effect_additions(effect, ds)
        features = features or default_features(ds)
        features += [f for f in add.get("features", []) if f not in features]
        terms += [t for t in add.get("terms", []) if t not in terms]
        feature_params.update(add.get("feature_params", {}))
    try:
        hidden = tuple(int(h) for h in args.hidden.split(",") if h.strip())
    except ValueError:
        raise ValueError(f"--hidden: expected sizes like 30 or 20,10, got {args.hidden!r}") from None
    hv = args.holdout_voltage.strip().lower()
    try:
        holdout_voltage = None if hv in ("none", "") else float(hv)
    except ValueError:
        raise ValueError(f"--holdout-voltage: expected a number or 'none', got {args.holdout_voltage!r}") from None
    dec = args.decimate.strip().lower()
    try:
        decimate = None if dec == "auto" else int(dec)
    except ValueError:
        raise ValueError(f"--decimate: expected a positive integer or 'auto', got {args.decimate!r}") from None
    if decimate is not None and decimate < 1:
        raise ValueError(f"--decimate: expected a positive integer, got {decimate}")
    return dict(features=features, hidden=hidden, activation=args.activation,
                holdout_voltage=holdout_voltage,
                holdout_tests=[s.strip() for s in args.holdout_tests.split(",") if s.strip()],
                decimate=decimate, terms=terms, feature_params=feature_params or None, seed=args.seed,
                zero_points=not args.no_zero_points, max_epochs=args.max_epochs,
                settings=_json_arg(args.settings, "settings", dict))


def effect_additions(effect: str, ds=None) -> dict:
    """{"features", "terms", "feature_params"} for an effect, from the diagnosis catalogue
    (given the dataset, the catalogue estimates the effect's parameters from it)."""
    try:
        from dampnet.diagnosis import catalogue
    except ImportError:
        raise ValueError(f"--add {effect}: effect catalogue (dampnet.diagnosis.catalogue) is not "
                         "available in this dampnet") from None
    try:
        add = None
        if ds is not None and ds.tests:
            try:
                add = catalogue.additions(effect, control=ds.tests[0].control_name, dataset=ds)
            except ImportError:  # parameter estimation not available: the catalogue's defaults
                add = None
        if add is None:
            add = catalogue.additions(effect)
    except KeyError as e:
        known = ""
        for attr in ("EFFECTS", "CATALOGUE", "effects"):
            obj = getattr(catalogue, attr, None)
            if obj is not None:
                known = f"; known: {', '.join(sorted(obj() if callable(obj) else obj))}"
                break
        raise ValueError(f"--add: unknown effect {effect!r}{known}") from e
    return add


class Progress:
    """A tqdm bar over epochs showing the current training and validation NRMSE."""

    def __init__(self, total: int, desc: str, enabled: bool):
        self.bar = None
        self.total, self.desc = total, desc
        self.enabled = enabled and sys.stderr.isatty()

    def __call__(self, rec: dict):
        if self.enabled and self.bar is None:  # opened at the first epoch: none for failed set-ups
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, desc=self.desc, unit="epoch", file=sys.stderr, leave=False)
        if self.bar is not None:
            # the MSE is of the force scaled to [-1, 1], so sqrt(MSE)/2 is the NRMSE (range definition)
            post = {"train_nrmse": f"{rec['train'] ** 0.5 / 2:.5f}"}
            if rec.get("val") is not None:
                post["val_nrmse"] = f"{rec['val'] ** 0.5 / 2:.5f}"
            self.bar.set_postfix(post, refresh=False)
            self.bar.update(1)
        return None

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def run(args) -> int:
    """Train and write MODEL_DIR; 0 on success, 2 (one-line message) on bad input."""
    from pathlib import Path

    from dampnet.data import DataError, load_dataset
    from dampnet.model import ModelError
    from dampnet.training.pipeline import model_metrics
    from dampnet.modeldir import save_model_dir

    from dampnet.outputs import check_output_dir

    out = Path(args.out)
    bar = None
    try:
        check_output_dir(out, "model", [args.data], args.force)  # before the work, again when writing
        ds = load_dataset(args.data)
        kw = training_kwargs(args, ds)
        bar = Progress(kw["max_epochs"], f"train {args.algorithm}", not args.quiet)
        from dampnet.training.pipeline import train_dataset

        t0 = time.perf_counter()
        model, info, split = train_dataset(ds, algorithm=args.algorithm, progress=bar, **kw)
        bar.close()
        t_train = time.perf_counter() - t0
        metrics = model_metrics(model, info, split)
        save_model_dir(model, metrics, out, force=args.force, prefix=args.prefix, inputs=[args.data])
    except (DataError, ModelError, FileExistsError, ValueError, OSError) as e:
        if bar is not None:
            bar.close()
        return error(str(e))
    if not args.quiet:
        print_summary(model, info, split, metrics, out, t_train)
    return 0


def print_summary(model, info, split, metrics, out, t_train) -> None:
    from dampnet.evaluation.metrics import format_table

    net = f"{model.n_inputs}-{'-'.join(map(str, model.hidden))}-1"
    print(f"{out}: {net} MLP ({', '.join(model.features)}), {info.algorithm}, {info.epochs} epochs "
          f"({info.stop_reason}) in {info.time_s:.1f} s ({t_train:.1f} s with data preparation)")
    if model.terms:
        print("physics terms: " + "; ".join(f"{t['kind']} {t['params']}" for t in model.terms))
    m = info.metrics
    print(f"NRMSE train {m.get('train', float('nan')):.4f}, validation {m.get('val', float('nan')):.4f}, "
          f"test {m.get('test', float('nan')):.4f} ({info.n_train} training samples, decimated by {split.decimate})")
    if "holdout" in metrics:
        print(format_table(metrics["holdout"], f"hold-out tests ({len(split.holdout_ids)}):"))
        lk = metrics.get("holdout_lookup", {})
        if "overall" in lk:
            print(f"lookup-table baseline on the hold-out: NRMSE {lk['overall']['nrmse']:.4f}")
    if "noise_floor" in metrics:
        print(f"noise floor of these data (rig sensor noise): NRMSE {metrics['noise_floor']['nrmse_range']:.4f}")
