"""Issue 29 (training options): every training setting and option is checked against its table
(dampnet.training.settings) before any training starts, in every front end (`dampnet train`,
`dampnet.train` = train_dataset, `dampnet.training.fit`), with a one-line error naming the setting
and its range; LM's and BR's damping loop is bounded whatever the settings; the hidden and input
limits are the runtime's own (dampnet._core)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

import dampnet
from dampnet import _core
from dampnet.cli import main
from dampnet.training import ALGORITHMS, fit
from dampnet.training.loop import Converged
from dampnet.training.settings import (
    ALGORITHM_TABLES,
    MAX_MU_INCREASES,
    MAX_RESTARTS,
    OPTIONS,
    check_request,
    check_settings,
    defaults,
)


class Trained(AssertionError):
    """Raised by the spies: the front end went past validation into data loading or training."""


@pytest.fixture
def no_training(monkeypatch):
    """Every way to the epochs fails loudly: data loading (CLI), data preparation (train_dataset), the
    epoch loop (fit). A validation error must come before any of them."""
    import importlib

    import dampnet.data
    import dampnet.training.pipeline as pipeline

    fit_module = importlib.import_module("dampnet.training.fitting")  # the module; dampnet.training.fit is fit()

    def spy(what):
        def f(*a, **k):
            raise Trained(f"{what} ran: validation came too late")
        return f

    monkeypatch.setattr(dampnet.data, "load_dataset", spy("load_dataset"))
    monkeypatch.setattr(pipeline, "prepare_training", spy("prepare_training"))
    monkeypatch.setattr(fit_module, "run", spy("the epoch loop"))


def bad_values(s) -> list:
    """A wrong type, NaN, +-inf, values just outside each end of the setting's range, an int beyond
    any float."""
    below = s.low if s.open_low else (s.low - 1 if s.kind == "whole" or s.low <= 0 else s.low / 2)
    above = s.high if s.open_high else (s.high + 1 if s.kind == "whole" else s.high * 2 + 1)
    out = ["x", math.nan, math.inf, -math.inf, below, above, True, 10**400]
    if s.kind == "whole":
        out.append(1.5)
    if s.none is None:
        out.append(None)
    if s.kind == "pair":  # each element, and the wrong length
        ok = s.low if not s.open_low else s.high / 2
        out = [[v, ok] for v in out if v is not None] + [[ok, below], [ok, above], [ok], 0.5, "x", None]
    return out


CASES = [(algo, name, v) for algo, table in ALGORITHM_TABLES.items() for name, s in table.items()
         for v in bad_values(s)]


def _id(case):
    return f"{case[0]}-{case[1]}-{case[2]!r}"


def one_line(text: str) -> str:
    assert text.count("\n") <= 1 and text.strip(), text
    return text.strip()


@pytest.mark.parametrize("front_end", ["cli", "api", "fit"])
@pytest.mark.parametrize("case", CASES, ids=[_id(c) for c in CASES])
def test_every_bad_setting_is_named_with_its_range_before_training(case, front_end, no_training, tmp_path, capsys):
    algo, name, value = case
    s = ALGORITHM_TABLES[algo][name]
    if front_end == "cli":
        data = tmp_path / "data"
        data.mkdir()
        rc = main(["train", str(data), "--out", str(tmp_path / "m"), "--quiet", "--algorithm", algo,
                   "--settings", json.dumps({name: value})])
        msg = one_line(capsys.readouterr().err)
        assert rc == 2 and not (tmp_path / "m").exists()
    else:
        with pytest.raises(ValueError) as e:
            if front_end == "api":
                dampnet.train(dampnet.Dataset(tests=[], source="none"), algorithm=algo, settings={name: value})
            else:
                X = np.linspace(0, 1, 30)[:, None]
                fit(X, X[:, 0] ** 2, features=["velocity"], algorithm=algo, settings={name: value})
        msg = one_line(str(e.value))
    assert f"{algo} setting {name} (" in msg and s.range_text() in msg, msg


@pytest.mark.parametrize("name", sorted(n for n, row in OPTIONS.items() if row.kind != "other"))
def test_every_request_option_is_named_with_its_range(name, no_training):
    s = OPTIONS[name]
    for value in bad_values(s):
        with pytest.raises(ValueError) as e:
            if name in ("restarts", "workers", "average"):
                kw = {"restarts": 2, name: value} if name == "workers" else {name: value}
                dampnet.train(dampnet.Dataset(tests=[], source="none"), **kw)
            elif name == "rest_fraction":  # fit's own option
                X = np.linspace(0, 1, 30)[:, None]
                fit(X, X[:, 0], features=["velocity"], rest_fraction=value)
            else:
                dampnet.train(dampnet.Dataset(tests=[], source="none"), **{name: value})
        msg = one_line(str(e.value))
        assert msg.startswith(f"{name} (") and s.range_text() in msg, msg


@pytest.mark.parametrize("argv, expect", [
    (["--max-epochs", "0"], "max_epochs (--max-epochs, the epoch limit): expected a whole number in [1, 1000000], got 0"),
    (["--max-epochs", "-5"], "got -5"),
    (["--seed", "-1"], "seed (--seed"),
    (["--decimate", "0"], "decimate (--decimate"),
    (["--workers", "0"], "workers (--workers"),
    (["--restarts", "99999999999999999999"], f"restarts (--restarts, trainings from different seeds, the best "
                                             f"kept): expected a whole number in [1, {MAX_RESTARTS}], got 99999999999999999999"),
    (["--restarts", "0"], f"in [1, {MAX_RESTARTS}]"),
    (["--hidden", "1000"], f"layer 1 in [1, {_core.MAX_HIDDEN}], layer 2 in [1, {_core.MAX_HIDDEN2}], both in"),
    (["--hidden", str(_core.MAX_HIDDEN + 1)], f"got [{_core.MAX_HIDDEN + 1}]"),
    (["--hidden", f"20,{_core.MAX_HIDDEN2 + 1}"], f"got [20, {_core.MAX_HIDDEN2 + 1}]"),
    (["--hidden", "30,20,10"], "one or two layer sizes"),
    (["--hidden", str(_core.MAX_HIDDEN // 2 + 1), "--average", "2", "--restarts", "2"],
     f"make a layer of {2 * (_core.MAX_HIDDEN // 2 + 1)}; dampnet's models hold at most {_core.MAX_HIDDEN}"),
    (["--average", "3", "--restarts", "2"], "average (--average): 3 restarts averaged, but only 2"),
    (["--average", "0"], "average (--average"),
    (["--algorithm", "lm", "--settings", '{"mu": -1}'], "lm setting mu (the initial damping"),
    (["--algorithm", "lm", "--settings", '{"mu_inc": 1.0}'],
     "lm setting mu_inc (the factor mu grows by after a rejected step): expected a number in (1, 1e+10], got 1.0"),
    (["--algorithm", "br", "--settings", '{"mu_inc": 0.5}'], "br setting mu_inc"),
    (["--settings", '{"mu": 1}'], "settings (--settings): the settings are one algorithm's; name it with --algorithm"),
    (["--algorithm", "lm", "--settings", '{"mu": NaN}'], "got nan"),
    (["--algorithm", "lm", "--settings", '{"mu": 1e9, "mu_max": 1e8}'],
     "settings (lm): mu <= mu_max expected, got mu 1000000000.0, mu_max 100000000.0"),
    (["--algorithm", "lm", "--settings", '{"bogus": 1}'],
     "lm: unknown settings 'bogus'; the lm settings are mu, mu_dec, mu_inc, mu_max, min_grad"),
    (["--algorithm", "adam", "--settings", '{"lr": 1e308}'], "adam setting lr"),
    (["--algorithm", "adam", "--settings", '{"batch_size": "x"}'], "adam setting batch_size"),
    (["--algorithm", "adam", "--settings", '{"lr": 0.01, "lr_min": 0.1}'], "lr_min <= lr expected"),
    (["--algorithm", "adam", "--settings", '{"cosine_epochs": 10}'], "lr_decay 1 with cosine_epochs"),
])
def test_the_issue_s_options_are_refused_before_the_data_are_read(argv, expect, no_training, tmp_path, capsys):
    rc = main(["train", str(tmp_path), "--out", str(tmp_path / "m"), "--quiet", *argv])
    err = one_line(capsys.readouterr().err)
    assert rc == 2 and expect in err, err
    assert not (tmp_path / "m").exists()


def test_limits_are_the_runtime_s(no_training):
    """The layer and input limits are read from the runtime (dampnet._core), and checked before any
    epoch: --hidden 65 trained for minutes, then failed when the model was checked."""
    assert check_request(hidden=[_core.MAX_HIDDEN])["hidden"] == (_core.MAX_HIDDEN,)
    assert check_request(hidden=30)["hidden"] == (30,)
    names = list(_core.FEATURE_NAMES)
    check_request(features=names[:_core.MAX_INPUTS])
    X = np.random.default_rng(0).uniform(-1, 1, (40, _core.MAX_INPUTS + 1))
    with pytest.raises(ValueError, match=rf"layer 1 in \[1, {_core.MAX_HIDDEN}\].*DN_MAX_HIDDEN and DN_MAX_HIDDEN2"):
        fit(X[:, :1], X[:, 0], features=["velocity"], hidden=(_core.MAX_HIDDEN + 1,))
    # layer 2 has its own, smaller limit (its storage is [layer 2][layer 1])
    assert _core.MAX_HIDDEN2 <= _core.MAX_HIDDEN
    check_request(hidden=[2, _core.MAX_HIDDEN2])
    with pytest.raises(ValueError, match=rf"layer 2 in \[1, {_core.MAX_HIDDEN2}\]"):
        check_request(hidden=[2, _core.MAX_HIDDEN2 + 1])
    # and so does layer 1 of a two-layer network (the [layer 2][layer 1] weights stay small)
    check_request(hidden=[_core.MAX_HIDDEN2, 2])
    with pytest.raises(ValueError, match=r"both in \[1, 64\] when there are two"):
        check_request(hidden=[_core.MAX_HIDDEN2 + 1, 2])
    with pytest.raises(ValueError, match=rf"at most {_core.MAX_INPUTS} inputs \(DN_MAX_INPUTS\)"):
        fit(X, X[:, 0], features=(names * 2)[:_core.MAX_INPUTS + 1], hidden=(3,))


@pytest.mark.parametrize("front_end", ["api", "fit"])
def test_an_unknown_activation_is_refused_before_the_data_are_prepared(front_end, no_training):
    with pytest.raises(ValueError, match=r"^activation \(--activation\): expected one of tanh, sigmoid, got 'relu'$"):
        if front_end == "api":
            dampnet.train(dampnet.Dataset(tests=[], source="none"), activation="relu")
        else:
            X = np.linspace(0, 1, 30)[:, None]
            fit(X, X[:, 0], features=["velocity"], activation="relu")


@pytest.mark.parametrize("split", ["abc", 5, [0.5, 0.5, math.nan], (0.7, 0.15, 0.15, 0.0), (1.2, -0.1, -0.1)])
def test_a_bad_split_is_named(split, no_training):
    X = np.linspace(0, 1, 30)[:, None]
    with pytest.raises(ValueError, match=r"^split: three non-negative fractions summing to 1 expected, got "):
        fit(X, X[:, 0], features=["velocity"], split=split)


def test_tables_match_the_algorithms_and_accept_their_own_ends():
    assert list(ALGORITHMS) == list(ALGORITHM_TABLES)
    for algo, cls in ALGORITHMS.items():
        assert cls.name == algo
        assert check_settings(algo, None) == defaults(algo)  # every default inside its own range
        for name, s in ALGORITHM_TABLES[algo].items():
            for end, is_open in ((s.low, s.open_low), (s.high, s.open_high)):
                if not is_open:
                    value = [end, end] if s.kind == "pair" else (int(end) if s.kind == "whole" else end)
                    assert s.check(value, name) is not None


class NoStepHelps:
    """A least-squares problem where every trial step is worse than the current point: LM and BR
    reject every damping value until their loop gives up."""

    n_params, n_train = 2, 4

    def __init__(self):
        self.trials = 0

    def residual_jacobian(self, x):
        return torch.ones(4, dtype=torch.float64), torch.eye(4, 2, dtype=torch.float64)

    def residual(self, x):
        self.trials += 1
        return torch.full((4,), 1e3, dtype=torch.float64)


@pytest.mark.parametrize("algo, forced", [
    ("lm", {"mu_inc": 1.0}), ("br", {"mu_inc": 0.5}), ("lm", {"mu": -1.0}), ("br", {"mu": -1.0, "mu_inc": 1.0}),
    ("lm", {"mu_inc": 1 + 1e-12}),  # a valid setting that would need ~3e13 increases to reach mu_max
])
def test_the_damping_loop_is_bounded_whatever_the_settings(algo, forced):
    prob = NoStepHelps()
    algo_obj = ALGORITHMS[algo](prob, torch.zeros(2, dtype=torch.float64))
    algo_obj.settings.update(forced)  # past validation, as a buggy caller could
    if "mu" in forced:
        algo_obj.mu = forced["mu"]
    prob.trials = 0
    with pytest.raises(Converged, match=f"mu was raised {MAX_MU_INCREASES} times in one epoch"):
        algo_obj.step()
    # each damping value tried at most once (a negative one may give no positive definite system to try)
    assert prob.trials == MAX_MU_INCREASES + 1 if "mu" not in forced else prob.trials <= MAX_MU_INCREASES + 1


def test_a_training_that_stops_before_its_first_epoch_is_an_error_not_a_model(monkeypatch):
    """An algorithm that stops at once (e.g. min_grad above the initial gradient, or mu NaN before
    it was refused) left the random initial network saved as the model, exit 0."""
    from dampnet.training.lm import LevenbergMarquardt

    def stop_at_once(self):
        raise Converged("gradient 0.5 below min_grad 1")

    monkeypatch.setattr(LevenbergMarquardt, "step", stop_at_once)
    X = np.random.default_rng(0).uniform(-1, 1, (60, 1))
    with pytest.raises(ValueError, match=r"^training stopped before its first epoch \(gradient 0.5 below min_grad 1\): "
                                         r"check the lm settings$"):
        fit(X, np.sin(3 * X[:, 0]), features=["velocity"], hidden=(3,), max_epochs=5)


def test_help_lists_every_setting_with_its_range(capsys):
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for algo, table in ALGORITHM_TABLES.items():
        assert f"{algo}: " in text
        for name, s in table.items():
            assert f"{name} {s.range_text()}" in text, name
