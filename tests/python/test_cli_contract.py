"""`dampnet diagnose` (--json, --report), `dampnet compare` and `dampnet info`: what they write
on success, and the one-line error contract on bad input (a missing or malformed model, a
missing or malformed dataset, an output that cannot be written): `dampnet: error: ...` as the
only line on stderr, exit status 2, no traceback. In process (main(argv)) for speed; an
exception escaping main would be the traceback a user sees, and fails the test."""

from __future__ import annotations

import json

import pytest

from dampnet.cli import main
from dampnet.data import write_dataset
from dampnet.rig import generate
from dampnet.modeldir import save_model_dir
from dampnet.training.pipeline import train_dataset

TINY_PLAN = {"name": "tiny", "frequencies_hz": [0.5, 2.0], "amplitudes_m": [0.0254],
             "voltages_v": [0.0, 2.25, 5.0], "samples": 800}
SUR = ["--surrogates", "4"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A tiny dataset, two small models trained on it, and malformed inputs."""
    root = tmp_path_factory.mktemp("cli")
    ds = generate(TINY_PLAN, seed=0)
    write_dataset(ds, root / "data")
    for name, seed in (("model_a", 0), ("model_b", 1)):
        model, _, _ = train_dataset(ds, max_epochs=10, decimate=4, seed=seed)
        save_model_dir(model, None, root / name)
    (root / "not_json").mkdir()
    (root / "not_json" / "model.json").write_text('{"w1": [1, 2,')
    (root / "not_a_model.json").write_text(json.dumps({"format": "something-else"}))
    (root / "bad_data").mkdir()
    (root / "bad_data" / "manifest.csv").write_text("test_id,file\nT1,T1.csv\n")
    (root / "a_file").write_text("not a directory\n")
    return root


def one_line_error(capsys, argv: list[str], *fragments: str) -> str:
    """Run the CLI expecting the bad-input contract; returns the error line."""
    capsys.readouterr()
    try:
        rc = main(argv)
    except BaseException as e:  # what the console script would print as a traceback
        pytest.fail(f"{argv}: raised {type(e).__name__}: {e} instead of a one-line error")
    err = capsys.readouterr().err
    assert rc == 2, (argv, rc, err)
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for f in fragments:
        assert f in err, (f, err)
    return err


# -- diagnose ---------------------------------------------------------------------------

def test_diagnose_writes_json_and_report(files, capsys):
    r = files
    out = r / "diag"
    out.mkdir()
    assert main(["diagnose", str(r / "model_a"), str(r / "data"), *SUR, "--json", str(out / "d.json"),
                 "--report", str(out / "report")]) == 0
    stdout = capsys.readouterr().out
    d = json.loads((out / "d.json").read_text())
    assert {"overall", "candidates", "verdict", "localisation"} <= set(d)
    assert d["overall"]["n_tests"] == 6 and f"over {d['overall']['n_tests']} tests" in stdout
    html = (out / "report" / "index.html").read_text()
    assert all(c["effect"] in html for c in d["candidates"])
    assert json.loads((out / "report" / "diagnosis.json").read_text())["candidates"] == d["candidates"]
    assert len(list((out / "report").glob("*.png"))) >= 3
    # '-' writes the same JSON to stdout (same seed: the same diagnosis)
    assert main(["diagnose", str(r / "model_a"), str(r / "data"), *SUR, "--json", "-"]) == 0
    printed = capsys.readouterr().out
    assert json.loads(printed[printed.index("{"):])["candidates"] == d["candidates"]


@pytest.mark.parametrize("model, data, fragment", [
    ("missing_model", "data", "missing_model"),
    ("not_json", "data", "not_json/model.json: line 1"),
    ("not_a_model.json", "data", "not a dampnet model"),
    ("model_a", "missing_data", "missing_data"),
    ("model_a", "bad_data", "manifest.csv: line 1"),
])
def test_diagnose_bad_input_is_one_line(files, capsys, model, data, fragment):
    one_line_error(capsys, ["diagnose", str(files / model), str(files / data), *SUR], fragment)


@pytest.mark.parametrize("count", ["-1", "0"])
def test_diagnose_nonpositive_surrogates_is_one_line_naming_the_option(files, capsys, count):
    # numpy's 'negative dimensions are not allowed' reached the user, naming no option
    one_line_error(capsys, ["diagnose", str(files / "model_a"), str(files / "data"), "--surrogates", count],
                   "--surrogates", count)


def test_diagnose_json_into_a_missing_directory_creates_it(files, capsys):
    # was a FileNotFoundError traceback after the whole diagnosis had run
    out = files / "no_such_dir_d" / "d.json"
    assert main(["diagnose", str(files / "model_a"), str(files / "data"), *SUR, "--json", str(out)]) == 0
    assert json.loads(out.read_text())["candidates"]


def test_diagnose_report_onto_a_file_is_one_line(files, capsys):
    # was a FileExistsError traceback from the report's mkdir, after the whole diagnosis
    one_line_error(capsys, ["diagnose", str(files / "model_a"), str(files / "data"), *SUR,
                            "--report", str(files / "a_file")], "a_file")
    assert (files / "a_file").read_text() == "not a directory\n"


# -- compare ----------------------------------------------------------------------------

def test_compare_tables_json_and_report(files, capsys):
    r = files
    out = r / "cmp"
    out.mkdir()
    assert main(["compare", str(r / "model_a"), str(r / "model_b"), str(r / "data"),
                 "--json", str(out / "c.json"), "--report", str(out / "report")]) == 0
    stdout = capsys.readouterr().out
    c = json.loads((out / "c.json").read_text())
    a, b = c["overall"]["a"]["nrmse"], c["overall"]["b"]["nrmse"]
    assert a != b and c["overall"]["nrmse_change_pct"] == pytest.approx(100 * (b / a - 1))
    assert f"NRMSE change: {c['overall']['nrmse_change_pct']:+.1f} %" in stdout
    assert [row["frequency_hz"] for row in c["per_frequency"]] == [0.5, 2.0] and len(c["per_test"]) == 6
    html = (out / "report" / "index.html").read_text()
    assert "dampnet compare" in html and "before (A)" in html and "after (B)" in html
    assert {p.name[:2] for p in (out / "report").glob("*.png")} == {"a_", "b_"}


@pytest.mark.parametrize("a, b, data, fragment", [
    ("missing_model", "model_b", "data", "missing_model"),
    ("model_a", "not_json", "data", "not_json/model.json: line 1"),
    ("model_a", "not_a_model.json", "data", "not a dampnet model"),
    ("model_a", "model_b", "missing_data", "missing_data"),
    ("model_a", "model_b", "bad_data", "manifest.csv: line 1"),
])
def test_compare_bad_input_is_one_line(files, capsys, a, b, data, fragment):
    one_line_error(capsys, ["compare", str(files / a), str(files / b), str(files / data)], fragment)


def test_compare_json_into_a_missing_directory_creates_it(files, capsys):
    out = files / "no_such_dir_c" / "c.json"
    assert main(["compare", str(files / "model_a"), str(files / "model_b"), str(files / "data"),
                 "--json", str(out)]) == 0
    assert json.loads(out.read_text())["overall"]["nrmse_change_pct"] is not None


def test_compare_report_onto_a_file_is_one_line(files, capsys):
    one_line_error(capsys, ["compare", str(files / "model_a"), str(files / "model_b"), str(files / "data"),
                            "--report", str(files / "a_file")], "a_file", "not a directory")
    assert (files / "a_file").read_text() == "not a directory\n"


@pytest.mark.parametrize("command", ["diagnose", "compare"])
def test_report_into_an_input_is_refused(files, capsys, command):
    models = [str(files / "model_a")] + ([str(files / "model_b")] if command == "compare" else [])
    one_line_error(capsys, [command, *models, str(files / "data"), *(SUR if command == "diagnose" else []),
                            "--report", str(files / "model_a")], "model_a", "input")
    assert not (files / "model_a" / "index.html").exists()


# -- info -------------------------------------------------------------------------------

def test_info_names_the_headers_and_library_that_exist(capsys):
    from pathlib import Path

    from dampnet import __version__, _core

    assert main(["info"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"dampnet {__version__} (C++ core {_core.__version__})"
    fields = dict(line.split(":", 1) for line in lines[1:3])
    assert (Path(fields["headers"].strip()) / "dampnet" / "dampnet.h").is_file()
    assert Path(fields["shared library"].strip()).is_file()
    assert any(line.startswith("MLP kernel:") for line in lines)


def test_info_without_the_shared_library_is_one_line(capsys, monkeypatch, tmp_path):
    """An install that lost its C library (or headers): info says so in one line, exit 2."""
    from dampnet import paths

    monkeypatch.setattr(paths, "_installed_root", lambda: tmp_path)
    one_line_error(capsys, ["info"], "libdampnet")


@pytest.mark.parametrize("argv, option", [
    (["vehicle", "M", "--speed", "80", "--speed", "90"], "--speed"),
    (["simulate", "M", "--road", "rough", "--road=bump"], "--road"),
    (["export", "M", "--header", "a.h", "--header", "b.h"], "--header"),
    (["train", "D", "--hidden", "30", "--hidden", "20"], "--hidden"),
])
def test_an_option_given_twice_is_refused(capsys, argv, option):
    """Issue 49, item 13: argparse kept the last of a repeated option silently (`vehicle --speed 80
    --speed 90` ran at 90). Every option that takes one value refuses a second, in every command;
    repeatable options (--add, --set) stay repeatable. Milliseconds."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert f"argument {option}: given twice" in capsys.readouterr().err


def test_every_single_value_option_refuses_a_repeat():
    import argparse

    from dampnet.cli import build_parser

    def walk(parser):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    yield from walk(sub)
            elif isinstance(action, argparse._StoreAction) and action.option_strings:
                yield action

    actions = list(walk(build_parser()))
    assert len(actions) > 100 and all(type(a).__name__ == "Once" for a in actions)


def test_export_set_twice_is_refused(tmp_path, capsys):
    from dampnet.modeldir import default_model_path

    argv = ["export", str(default_model_path()), "--fmu", str(tmp_path / "q.fmu"), "--what", "quarter-car",
            "--set", "m_s=1", "--set", "m_s=2"]
    assert main(argv) == 2
    assert "--set m_s: given twice" in capsys.readouterr().err
    assert not (tmp_path / "q.fmu").exists()
