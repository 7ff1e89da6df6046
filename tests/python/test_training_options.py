"""The training options' one table (dampnet.training.settings.OPTIONS): each default is stated once,
and an option added as docs/recipes.md says reaches every front end and the model."""

from __future__ import annotations

import argparse
import io
import re
import tokenize
from pathlib import Path

import pytest

from dampnet import _core
from dampnet.training.settings import OPTIONS, Option, register

PACKAGE = Path(__file__).resolve().parents[2] / "python" / "dampnet"

#: (what, the names a line must mention, the literal it must hold): a default's statement
DEFAULTS = [
    ("max_epochs 1000", ("max_epochs",), {"1000"}),
    ("hidden 30", ("hidden",), {"30", "(30,)", "[30]", "'30'", '"30"'}),
    ("hold-out 2.25 V", ("holdout",), {"2.25", "'2.25'", '"2.25"'}),
    ("activation tanh", ("activation",), {"'tanh'", '"tanh"'}),
]


def code_lines(root: Path = PACKAGE) -> list[tuple[str, int, list[str]]]:
    """(file, line, the line's code tokens) of every module: names, numbers and strings, but not
    comments nor docstrings (a string token that is a statement of its own)."""
    out = []
    for path in sorted(root.rglob("*.py")):
        lines: dict[int, list[str]] = {}
        prev = tokenize.NEWLINE
        for tok in tokenize.generate_tokens(io.StringIO(path.read_text(encoding="utf-8")).readline):
            docstring = tok.type == tokenize.STRING and prev in (tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT)
            if tok.type in (tokenize.NAME, tokenize.NUMBER, tokenize.STRING, tokenize.OP) and not docstring:
                lines.setdefault(tok.start[0], []).append(tok.string)
            if tok.type not in (tokenize.NL, tokenize.COMMENT):
                prev = tok.type
        out += [(str(path.relative_to(root)), n, toks) for n, toks in lines.items()]
    return out


def homes(names: tuple[str, ...], literals: set[str], root: Path = PACKAGE) -> list[str]:
    """The lines of code that mention one of `names` and hold one of `literals` (a tuple's
    tokens apart: "(30,)" is found as its "30"), not in a comparison (`activation == "tanh"` is
    the activation's implementation, not its default)."""
    found = []
    for path, n, toks in code_lines(root):
        mentions = any(name in t.lower() for t in toks for name in names)
        if mentions and any(t in literals for t in toks) and not {"==", "!="} & set(toks):
            found.append(f"{path}:{n}")
    return found


@pytest.mark.parametrize("what,names,literals", DEFAULTS, ids=[d[0] for d in DEFAULTS])
def test_each_default_is_stated_once(what, names, literals):
    """grep (as tokens: code only, not comments or docstrings) finds each of the issue's defaults
    in one line of python/dampnet, its row of the options table. Cost: 1.5 s."""
    found = homes(names, literals)
    assert len(found) == 1 and found[0].startswith("training/settings.py"), (what, found)


def test_the_activations_are_the_runtimes():
    """No module lists the activations by hand: the table's choices, the model's check and the
    help are the runtime's registry, dampnet._core.ACTIVATIONS. Cost: 1 s."""
    from dampnet.model import ACTIVATIONS

    assert OPTIONS["activation"].choices == ACTIVATIONS == tuple(_core.ACTIVATIONS)
    names = set(_core.ACTIVATIONS)
    lists = [f"{p}:{n}" for p, n, toks in code_lines() if len(names & {t[1:-1] for t in toks if t[0] in "'\""}) > 1]
    assert lists == []


def test_the_grep_finds_a_second_default(tmp_path):
    """The grep above can fail: a second statement of a default is found, a comment or a docstring
    saying it is not. Cost: 0.01 s."""
    (tmp_path / "a.py").write_text('def f(max_epochs: int = 1000):\n    """max_epochs 1000, as said"""\n'
                                   '    return 1  # max_epochs = 1000\n')
    (tmp_path / "b.py").write_text('ROWS = [("max_epochs", "whole", 1, 10**6, 1000)]\n')
    assert homes(("max_epochs",), {"1000"}, tmp_path) == ["a.py:1", "b.py:1"]


@pytest.fixture
def knob():
    """An option registered as docs/recipes.md says (one row), removed afterwards."""
    row = register(Option("test_knob", "real", 0, 10, 2.5, "a knob of this test", unit="N", cli="--test-knob",
                          sweep="test_knob"))
    try:
        yield row
    finally:
        del OPTIONS["test_knob"]


def test_an_option_added_as_the_recipe_says_reaches_every_front_end(knob, tmp_path):
    """One row added to the table: `dampnet train --help` lists it with its help, the command line
    parses it into the request, the sweep's [training] has its key with its default, the check
    refuses a value out of its range (the CLI's, the sweep's and the API's alike), and the trained
    model records it in model.meta["request"]. Cost: 5 s (one tiny training)."""
    import dampnet
    from dampnet.commands import train
    from dampnet.commands.training_options import training_request
    from dampnet.recipes.training import TrainingRequest
    from dampnet.rig import generate
    from dampnet.sweep import train_cell
    from dampnet.sweep.spec import SpecError, parse_spec, training_params

    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    train.add_parser(sub)
    helps = {o: a.help for a in sub.choices["train"]._actions for o in a.option_strings}
    assert helps["--test-knob"].startswith("a knob of this test [N]") and "default 2.5" in helps["--test-knob"]
    args = parser.parse_args(["train", "data.csv", "--out", "m", "--test-knob", "3"])
    assert training_request(args).test_knob == 3.0
    args = parser.parse_args(["train", "data.csv", "--out", "m"])
    assert training_request(args).test_knob == 2.5                    # the table's default

    keys = {p.key: p for p in training_params()}
    assert keys["test_knob"].default == 2.5 and keys["test_knob"].help.startswith("a knob of this test")
    spec = parse_spec({"training": {"datasets": "rig:quick", "test_knob": 4}})
    assert spec.sections["training"].axes["test_knob"] == [4.0]
    with pytest.raises(SpecError, match=r"training.test_knob: test_knob \(--test-knob, a knob of this test\): "
                                        r"expected a number in \[0, 10\], got 11"):
        parse_spec({"training": {"datasets": "rig:quick", "test_knob": 11}})
    with pytest.raises(ValueError, match=r"test_knob \(--test-knob, a knob of this test\): expected a number"):
        TrainingRequest(test_knob=11).check()
    params = {p.name: p.default for p in training_params()}
    assert train_cell.request({**params, "test_knob": 4.0}).test_knob == 4.0

    model, _, _ = dampnet.train(generate("quick", seed=0), test_knob=3.5, decimate=50, max_epochs=3)
    assert model.meta["request"]["test_knob"] == 3.5
    assert model.meta["request"]["max_epochs"] == 3 and model.meta["request"]["hidden"] == [30]


def test_the_docs_table_is_the_options_table():
    """docs/training.md's "Training options" is the table as options_markdown() writes it now (an
    option added, changed or removed without regenerating it fails here). Cost: 0.01 s."""
    from dampnet.training.options_table import TABLE_END, TABLE_START
    from dampnet.training.settings import options_markdown

    text = (PACKAGE.parents[1] / "docs" / "training.md").read_text(encoding="utf-8")
    found = re.search(re.escape(TABLE_START) + "(.*?)" + re.escape(TABLE_END), text, re.S)
    assert found is not None and found.group(1) == options_markdown()
    before = options_markdown()
    register(Option("test_knob", "real", 0, 10, 2.5, "a knob of this test"))
    try:
        assert options_markdown() != before and "| test_knob |" in options_markdown()
    finally:
        del OPTIONS["test_knob"]
