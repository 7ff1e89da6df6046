"""The export-target recipe (docs/recipes.md, "Export targets"), proved: the doc's block, run as
written from this test (a user's module: a target and its own option,
dampnet.recipes.export_targets), gives `dampnet export` options, written by the command beside the
built-in targets, with their defaults, and refused where they do not apply; the built-in options are refused for targets they do not apply to,
naming the targets they do. Sweeps do not export, so an export target has no sweep front end."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from dampnet.cli import build_parser, main
from dampnet.modeldir import default_model, save_model_dir
from dampnet.recipes import export_targets
from recipe_tree import run_doc_block


@pytest.fixture
def forces_target():
    """docs/recipes.md's export-target recipe, run as written (a user's module: --forces-csv OUT.csv,
    the output, and --points N, default 11); removed after the test. Yields its namespace with the
    registered target as "target"."""
    namespace = run_doc_block("Export targets")
    try:
        yield {**namespace, "target": export_targets.get("forces-csv")}
    finally:
        export_targets.unregister("forces-csv")
    assert "--points" not in export_targets.OPTIONS and "--prefix" in export_targets.OPTIONS


@pytest.fixture
def model_dir(tmp_path):
    return save_model_dir(default_model(), None, tmp_path / "model")


def _error(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("dampnet: error: ") and err.count("\n") == 1, err
    return err


def test_a_target_registered_here_is_written_by_dampnet_export(forces_target, model_dir, tmp_path, capsys):
    help_text = build_parser()._subparsers._group_actions[0].choices["export"].format_help()
    assert "--forces-csv OUT.csv" in help_text and "[forces-csv]" in help_text
    out = tmp_path / "f.csv"
    assert main(["export", str(model_dir), "--forces-csv", str(out)]) == 0
    assert f"{out}: 11 forces [N]" in capsys.readouterr().out          # --points' default
    rows = list(csv.reader(out.open()))[1:]
    model = default_model()
    v = np.array([float(r[0]) for r in rows])
    k = model.features.index("velocity")
    assert len(rows) == 11 and v[0] == model.sat_lo[k] and v[-1] == model.sat_hi[k]
    # the forces are the model's (the runtime's own predict at those points): a damper's force grows with velocity
    f = np.array([float(r[1]) for r in rows])
    assert f[-1] > f[5] > f[0]
    # with a built-in target in one command line; the target's checks, then its refusal of an existing file
    assert main(["export", str(model_dir), "--forces-csv", str(tmp_path / "g.csv"), "--points", "3",
                 "--header", str(tmp_path / "m.h")]) == 0
    printed = capsys.readouterr().out
    assert "3 forces" in printed and "C/C++ header, prefix dn_model" in printed
    assert len(list(csv.reader((tmp_path / "g.csv").open()))) == 4 and (tmp_path / "m.h").is_file()
    assert main(["export", str(model_dir), "--forces-csv", str(tmp_path / "h.csv"), "--points", "1"]) == 2
    assert "--points: expected an integer >= 2, got 1" in _error(capsys) and not (tmp_path / "h.csv").exists()
    assert main(["export", str(model_dir), "--forces-csv", str(out)]) == 2
    assert "refusing to overwrite" in _error(capsys)


def test_options_are_refused_for_targets_they_do_not_apply_to(forces_target, model_dir, tmp_path, capsys):
    cases = [
        (["--header", "h.h", "--points", "5"], "--points does not apply to header; it applies to forces-csv: "
                                              "add --forces-csv OUT.csv"),
        (["--forces-csv", "f.csv", "--prefix", "p"], "--prefix does not apply to forces-csv; it applies to header: "
                                                     "add --header OUT.h"),
        (["--header", "h.h", "--fmi", "3"], "--fmi does not apply to header; it applies to fmu-damper, "
                                            "fmu-quarter-car: add --fmu OUT.fmu"),
        (["--fmu", "d.fmu", "--controller", "skyhook_onoff"],
         "--controller does not apply to fmu-damper; it applies to fmu-quarter-car: add --what quarter-car"),
        (["--onnx", "o.onnx", "--target", "cortex-m4"], "--target does not apply to onnx; it applies to mcu: "
                                                        "add --out DIR"),
        (["--target", "cortex-m4"], "--target alone selects nothing to export; it applies to mcu: add --out DIR"),
        (["--out", "fw"], "--out is the microcontroller folder: give --target cortex-m4|cortex-m7"),
        (["--force"], "nothing to export: give --fmu OUT.fmu, --onnx OUT.onnx, --header OUT.h, "
                      "--target cortex-m4|cortex-m7 --out DIR, "
                      "--forces-csv OUT.csv"),
    ]
    for args, message in cases:
        args = [str(tmp_path / a) if a.endswith((".h", ".csv", ".fmu", ".onnx")) or a == "fw" else a for a in args]
        assert main(["export", str(model_dir), *args]) == 2, args
        assert message in _error(capsys), (args, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model"]    # nothing written


def test_unknown_names_are_refused_listing_the_registry(capsys):
    with pytest.raises(SystemExit) as e:
        main(["export", "m", "--target", "cortex-m0", "--out", "x"])
    assert e.value.code == 2 and "invalid choice: 'cortex-m0' (choose from 'cortex-m4', 'cortex-m7')" in \
        capsys.readouterr().err
    with pytest.raises(ValueError, match="'zip' is not an export target; valid: fmu-damper, fmu-quarter-car, onnx, "
                                         "header, mcu"):
        export_targets.get("zip")
    with pytest.raises(ValueError, match="already registered"):
        export_targets.register(export_targets.TARGETS["onnx"])
    with pytest.raises(ValueError, match="option --csv is not registered"):
        export_targets.register(export_targets.ExportTarget("csv", "", "--csv", ("--csv",), print))
