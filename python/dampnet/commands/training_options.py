"""The training options `train` and `compare-algorithms` share, their parsing, and the epoch bar."""

from __future__ import annotations

import argparse
import sys

from dampnet.commands.common import json_arg, read_json_file

#: where --add EFFECT's parameters come from (stated in the help of train and compare-algorithms)
ADD_RULE = ("its parameters (a lag's time constant, a pre-sliding length) are the diagnosis's when "
            "--diagnosis FILE is given; else a lag's time constant is estimated from DATA alone "
            "(dampnet.diagnosis.estimate) and the others take the catalogue's defaults")


def field_help(name: str, spelling: str = "") -> str:
    """An option's help: what the request field means (dampnet.recipes.training.FIELDS, the
    one text the sweep's keys share), then how the command line spells it."""
    from dampnet.recipes.training import FIELDS

    return FIELDS[name].help() + (f"; {spelling}" if spelling else "")


def add_training_options(p: argparse.ArgumentParser, algorithm: bool = True) -> None:
    """Options shared by `train` and `compare-algorithms`."""
    from dampnet.effects import CATALOGUE

    addable = ", ".join(k for k, e in CATALOGUE.items() if e.adds is not None)
    p.add_argument("--features", default=None,
                   help=field_help("features", "comma-separated, e.g. velocity,acceleration,voltage,temperature"))
    p.add_argument("--terms", default=None,
                   help=field_help("terms", 'JSON, e.g. \'[{"kind": "position_poly"}]\'; terms without "params" are '
                                            "fitted by least squares, the MLP learns the rest"))
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help=field_help("add", f"repeatable; the effect catalogue: {addable}; `dampnet rig "
                                          f"--list-effects`; {ADD_RULE}"))
    p.add_argument("--diagnosis", default=None, metavar="FILE",
                   help=field_help("diagnosis", "the JSON of `dampnet diagnose --json FILE` (the same additions as "
                                                "the demo's improve stage)"))
    if algorithm:
        from dampnet.recipes.training import AUTO
        from dampnet.training.settings import ALGORITHM_NAMES

        p.add_argument("--algorithm", default=AUTO, choices=[AUTO, *sorted(ALGORITHM_NAMES)],
                       help=field_help("algorithm", "auto (the default; bench/RESULTS.md 'Few dyno tests'), "
                                       + ", ".join(f"{k} {v}" for k, v in ALGORITHM_NAMES.items())))
    p.add_argument("--hidden", default="30", help=field_help("hidden", "e.g. 30 or 20,10 (default 30)"))
    p.add_argument("--activation", default="tanh", choices=["tanh", "sigmoid"],
                   help=field_help("activation", "default tanh, MATLAB's tansig"))
    p.add_argument("--holdout-voltage", default="2.25",
                   help=field_help("holdout_voltage", "every test at this nominal control value; default 2.25, "
                                                          "'none' for none"))
    p.add_argument("--holdout-tests", default="", help=field_help("holdout_tests", "comma-separated"))
    p.add_argument("--decimate", default="auto",
                   help=field_help("decimate", "N, or 'auto' (the default; 25 at 5 kHz, 50 on large data)"))
    from dampnet.training.settings import OPTIONS

    rest = OPTIONS["rest_target"]
    p.add_argument("--rest-target", default=rest.default, choices=rest.choices,
                   help=field_help("rest_target", f"default {rest.default}"))
    from dampnet.training.settings import MAX_EPOCHS, MAX_SEED, TRAIN_DEFAULTS, settings_help

    p.add_argument("--max-epochs", type=int, default=1000, help=field_help("max_epochs", f"1..{MAX_EPOCHS} (default 1000)"))
    p.add_argument("--seed", type=int, default=0,
                   help=field_help("seed", f"0..{MAX_SEED} (default 0)"))
    prior = OPTIONS["control_prior"]
    p.add_argument("--control-prior", type=float, default=prior.default, metavar="W",
                   help=field_help("control_prior", f"W in {prior.range_text()} (default {prior.default:g}; "
                                                    "dampnet.training.control_prior; bench/RESULTS.md 'Few dyno tests')"))
    mono = OPTIONS["monotone_prior"]
    p.add_argument("--monotone-prior", type=float, default=mono.default, metavar="W",
                   help=field_help("monotone_prior", f"W in {mono.range_text()} (default {mono.default:g}; "
                                                     "dampnet.training.monotone_prior)"))
    p.add_argument("--settings", default=None,
                   help=field_help("settings", 'JSON, e.g. \'{"mu_max": 1e8}\' or \'{"lr": 0.01}\'; each with its '
                                               f"range: {settings_help(TRAIN_DEFAULTS)}"))


def training_kwargs(args, ds) -> tuple[dict, list[dict]]:
    """(train_dataset keyword arguments, what each --add added) from the parsed options, for
    `compare-algorithms` (each algorithm checks its own settings when it trains).

    --add EFFECT goes through dampnet.recipes.training.plan (apply_additions, as the demo's
    improve stage does): with --diagnosis FILE the diagnosis's parameters, else parameters
    estimated from the data (dampnet.diagnosis.estimate). ValueError on bad options.
    """
    from dampnet.recipes.training import plan

    p = plan(ds, training_request(args), check=False)
    return p.kw, p.added


def option_kwargs(args) -> dict:
    """train_dataset keyword arguments from the parsed options, before any --add (no data needed);
    ValueError on options that do not parse (their ranges are the training layer's to check)."""
    return training_request(args).kwargs()


def training_request(args):
    """The dampnet.recipes.training.TrainingRequest of the parsed options (`train`'s and
    `compare-algorithms`'); ValueError on options that do not parse (their ranges are the
    request's check, dampnet.training.settings). --diagnosis FILE is read here."""
    from dampnet.recipes.training import AUTO, TrainingRequest
    from dampnet.training.restarts import DEFAULT_SCORE

    features = [f.strip() for f in args.features.split(",") if f.strip()] if args.features else None
    terms = json_arg(args.terms, "terms", list) or []
    for t in terms:
        if not isinstance(t, dict) or "kind" not in t:
            raise ValueError(f"--terms: each term must be an object with a 'kind', got {t!r}")
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
    diagnosis = None
    if args.diagnosis is not None:
        if not args.add:
            raise ValueError("--diagnosis: name the effect(s) to add with --add EFFECT (e.g. the diagnosis's verdict)")
        diagnosis = read_json_file(args.diagnosis, "the diagnosis JSON of `dampnet diagnose --json`")
    restarts = 1
    if getattr(args, "restarts", None) is not None:
        restarts = AUTO if str(args.restarts).strip().lower() == AUTO else whole(args.restarts, "restarts")
    return TrainingRequest.of(
        features=features, algorithm=getattr(args, "algorithm", "lm"), hidden=hidden, activation=args.activation,
        holdout_voltage=holdout_voltage, holdout_tests=[s.strip() for s in args.holdout_tests.split(",") if s.strip()],
        decimate=decimate, terms=terms, seed=args.seed,
        rest_target=args.rest_target,
        max_epochs=args.max_epochs, settings=json_arg(args.settings, "settings", dict), add=list(args.add),
        diagnosis=diagnosis, diagnosis_source=args.diagnosis, restarts=restarts,
        restart_score=getattr(args, "restart_score", DEFAULT_SCORE), average=getattr(args, "average", 1),
        control_prior=args.control_prior, monotone_prior=args.monotone_prior)


def whole(text: str, name: str) -> int:
    """--NAME's value as a whole number; ValueError (exit 2, one line) otherwise."""
    try:
        return int(str(text).strip())
    except ValueError:
        raise ValueError(f"--{name}: expected a whole number{' or auto' if name == 'restarts' else ''}, "
                         f"got {text!r}") from None


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
