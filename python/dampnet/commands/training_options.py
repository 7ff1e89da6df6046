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
    """An option's help: what it means (its row of the options table, dampnet.training.settings.OPTIONS,
    the one text the sweep's keys share), then how the command line spells it."""
    from dampnet.training.settings import OPTIONS

    return OPTIONS[name].help() + (f"; {spelling}" if spelling else "")


def _default_text(row) -> str:
    value = row.cli_default if row.cli_default is not None else row.default
    if value is None or value == ():
        return ""
    if isinstance(value, tuple):
        value = ",".join(map(str, value))
    return f"default {value:g}" if isinstance(value, float) else f"default {value}"


def add_training_options(p: argparse.ArgumentParser, algorithm: bool = True, train: bool = False) -> None:
    """The options of the options table's rows with a `cli` (dampnet.training.settings.OPTIONS):
    those `train` and `compare-algorithms` share (`algorithm`: --algorithm too), and with `train`
    the train_only ones (--restarts, --workers, ...). Each is None unless given: training_request
    takes the table's default (or the row's cli_default)."""
    from dampnet.effects import CATALOGUE
    from dampnet.training.restarts import SCORE_HELP
    from dampnet.training.settings import OPTIONS, TRAIN_DEFAULTS, settings_help

    addable = ", ".join(k for k, e in CATALOGUE.items() if e.adds is not None)
    extra = {"add": f"repeatable; the effect catalogue: {addable}; `dampnet rig --list-effects`; {ADD_RULE}",
             "settings": 'JSON, e.g. \'{"mu_max": 1e8}\' or \'{"lr": 0.01}\'; each with its range: '
                         + settings_help(TRAIN_DEFAULTS),
             "restart_score": "; ".join(f"{k}: {v}" for k, v in SCORE_HELP.items())}
    for row in OPTIONS.values():
        if row.cli is None or (row.train_only and not train) or (row.name == "algorithm" and not algorithm):
            continue
        kw: dict = {"default": None}
        if row.name == "add":
            kw["action"] = "append"
        elif row.choices:
            kw["choices"] = list(row.choices)
        elif row.kind in ("whole", "real") and row.name not in PARSE:
            kw["type"] = int if row.kind == "whole" else float
            if row.kind == "whole":
                kw["help_range"] = f"{row.range_text()}"
        rng = kw.pop("help_range", "")
        if row.kind == "real" and row.name not in PARSE:
            rng = f"{row.metavar or 'value'} in {row.range_text()}"
        words = "; ".join(w for w in (row.cli_help, extra.get(row.name, ""), rng, _default_text(row)) if w)
        p.add_argument(row.cli, metavar=row.metavar, help=field_help(row.name, words), **kw)


def _words(text: str) -> tuple[str, ...]:
    return tuple(s.strip() for s in text.split(",") if s.strip())


def _hidden(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(h) for h in text.split(",") if h.strip())
    except ValueError:
        raise ValueError(f"--hidden: expected sizes like 30 or 20,10, got {text!r}") from None


def _holdout_voltage(text: str) -> float | None:
    hv = text.strip().lower()
    try:
        return None if hv in ("none", "") else float(hv)
    except ValueError:
        raise ValueError(f"--holdout-voltage: expected a number or 'none', got {text!r}") from None


def _decimate(text: str) -> int | None:
    dec = text.strip().lower()
    try:
        return None if dec == "auto" else int(dec)
    except ValueError:
        raise ValueError(f"--decimate: expected a positive integer or 'auto', got {text!r}") from None


def _terms(text: str) -> list:
    terms = json_arg(text, "terms", list) or []
    for t in terms:
        if not isinstance(t, dict) or "kind" not in t:
            raise ValueError(f"--terms: each term must be an object with a 'kind', got {t!r}")
    return terms


def _restarts(text: str) -> int | str:
    from dampnet.training.settings import AUTO

    return AUTO if str(text).strip().lower() == AUTO else whole(text, "restarts")


#: how the command line spells the values its kind does not say (text -> value); the others are
#: argparse's int or float, or a choice
PARSE = {"features": lambda t: list(_words(t)) or None, "hidden": _hidden, "holdout_voltage": _holdout_voltage,
         "holdout_tests": lambda t: list(_words(t)), "decimate": _decimate, "terms": _terms,
         "settings": lambda t: json_arg(t, "settings", dict), "restarts": _restarts,
         "workers": lambda t: whole(t, "workers"), "add": list}


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
    `compare-algorithms'`): each request row's option (PARSE: its text to a value), its cli_default
    or the table's default when not given; ValueError on options that do not parse (their ranges
    are the request's check, dampnet.training.request). --diagnosis FILE is read here."""
    from dampnet.recipes.training import TrainingRequest
    from dampnet.training.settings import OPTIONS

    given = {}
    for row in OPTIONS.values():
        dest = row.cli[2:].replace("-", "_") if row.cli else None
        if not row.request or dest is None or not hasattr(args, dest) or row.name == "diagnosis":
            continue
        text = getattr(args, dest)
        if text is None:
            if row.cli_default is not None:
                given[row.name] = row.cli_default
            continue
        given[row.name] = PARSE[row.name](text) if row.name in PARSE else text
    if args.diagnosis is not None:
        if not args.add:
            raise ValueError("--diagnosis: name the effect(s) to add with --add EFFECT (e.g. the diagnosis's verdict)")
        given["diagnosis"] = read_json_file(args.diagnosis, "the diagnosis JSON of `dampnet diagnose --json`")
        given["diagnosis_source"] = args.diagnosis
    return TrainingRequest.of(**given)


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
