"""The installed package is complete: the wheel built from this tree (a regular, non-editable
`pip install`, see wheel_env.py) carries every file a command reads at run time, and every
command's quick path runs from it with no source tree on the path. The rest of the suite runs
the editable install, which finds missing files in the source tree and so cannot see this.
`dampnet demo --quick` runs from this same wheel install in test_demo.py (not twice)."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import pytest

from cbuild import ROOT
from wheel_env import wheel_env

# Tiny rig campaign (6 tests x 800 samples): enough for every command, cheap to train on.
TINY_PLAN = {"name": "tiny", "frequencies_hz": [0.5, 2.0], "amplitudes_m": [0.0254],
             "voltages_v": [0.0, 2.25, 5.0], "samples": 800}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    return wheel_env(tmp_path_factory)


@pytest.fixture(scope="module")
def work(tmp_path_factory) -> Path:
    """The commands' working directory: outside the source tree."""
    return tmp_path_factory.mktemp("wheel_cwd")


def ok(proc) -> str:
    """The stdout of a command that must have succeeded (else its output, for the log)."""
    assert proc.returncode == 0, f"exit {proc.returncode}\n--- stdout\n{proc.stdout[-3000:]}\n" \
                                 f"--- stderr\n{proc.stderr[-3000:]}"
    assert "Traceback" not in proc.stderr, proc.stderr[-3000:]
    return proc.stdout


@pytest.fixture(scope="module")
def dataset(wheel, work) -> Path:
    (work / "tiny.json").write_text(json.dumps(TINY_PLAN))
    ok(wheel.dampnet("rig", "data", "--plan", "tiny.json", "--no-progress", cwd=work))
    return work / "data"


@pytest.fixture(scope="module")
def model(wheel, work, dataset) -> Path:
    ok(wheel.dampnet("train", dataset, "--out", "model", "--quiet", "--max-epochs", "15",
                     "--decimate", "4", cwd=work))
    return work / "model"


def test_the_wheel_carries_the_package_and_every_runtime_file(wheel):
    names = set(zipfile.ZipFile(wheel.wheel).namelist())
    # every file of the Python package (modules and package data such as demo/controller.c)
    src = ROOT / "python" / "dampnet"
    package = {f"dampnet/{p.relative_to(src).as_posix()}" for p in src.rglob("*")
               if p.is_file() and "__pycache__" not in p.parts and p.suffix not in (".pyc", ".so")}
    assert package - names == set()
    # the typed stub of the extension and the marker that makes mypy and editors read it
    assert {"dampnet/_core.pyi", "dampnet/py.typed"} <= names
    # what CMake installs for the C side: `dampnet info`'s headers and library, `dampnet bench`'s
    # harness sources and the default model (header and model.json), the demo's C program
    for f in ("include/dampnet/dampnet.h", "include/dampnet/dn_config.h", "include/dampnet/dn_xmacro.h",
              "include/dampnet/dn_types.h", "include/dampnet/mlp.hpp", "include/dampnet/loop.hpp",
              "include/dampnet/fullcar.hpp",
              "include/dn_model_default.h", "include/dn_model_default.json", "lib/libdampnet.so",
              "bench/bench_mlp.cpp", "bench/latency.hpp", "demo/controller.c",
              # `dampnet export --target` (dampnet.export.mcu)
              "src/c_api_loop.cpp", "src/internal.hpp", "cmake/arm-none-eabi.cmake", "embedded/firmware.c",
              "embedded/mps2.ld"):
        assert f"dampnet/{f}" in names, f
    assert any(n.startswith("dampnet/_core.") and n.endswith(".so") for n in names)
    assert (ROOT / "export" / "dn_model_default.json").read_bytes() == \
        zipfile.ZipFile(wheel.wheel).read("dampnet/include/dn_model_default.json")


def test_dampnet_comes_only_from_the_wheel(wheel, work):
    """Every dampnet module the CLI loads, the extension, the headers and the C library are the
    installed copies in the fresh venv; no sys.path entry is the source tree."""
    out = ok(wheel.python_code(
        "import json, sys, dampnet, dampnet._core, dampnet.cli\n"
        "from dampnet import paths\n"
        "dampnet.cli.build_parser()\n"
        "print(json.dumps({'modules': {n: getattr(m, '__file__', None) for n, m in sys.modules.items()\n"
        "                              if n == 'dampnet' or n.startswith('dampnet.')},\n"
        "                  'path': sys.path, 'include': str(paths.include_dirs()[0]),\n"
        "                  'lib': str(paths.shared_library())}))", cwd=work))
    res = json.loads(out)
    site = str(wheel.site) + "/"
    assert len(res["modules"]) > 20 and {"dampnet._core", "dampnet.commands.bench"} <= set(res["modules"])
    assert all(f is not None and f.startswith(site + "dampnet/") for f in res["modules"].values()), res
    assert res["include"].startswith(site) and res["lib"].startswith(site)
    src_dirs = {str(ROOT), str(ROOT / "python"), str(ROOT / "tests" / "python")}
    assert src_dirs.isdisjoint(res["path"])  # ('' is `python -c`'s cwd: the empty work directory)


def test_info_and_version(wheel, work):
    out = ok(wheel.dampnet("info", cwd=work))
    assert f"headers:        {wheel.site}/dampnet/include" in out
    assert f"shared library: {wheel.site}/dampnet/lib/libdampnet.so" in out
    assert ok(wheel.dampnet("--version", cwd=work)).startswith("dampnet ")


def test_rig_and_train(dataset, model):
    assert (dataset / "manifest.csv").is_file() and len(list(dataset.glob("*.csv"))) == 7
    assert sorted(p.name for p in model.iterdir()) == ["envelope.json", "envelope.npz", "metrics.json", "model.h",
                                                       "model.json"]


def test_evaluate(wheel, work, model, dataset):
    ok(wheel.dampnet("evaluate", model, dataset, "--json", "evaluate.json", "--plots", "evaluate_plots",
                     cwd=work))
    rep = json.loads((work / "evaluate.json").read_text())
    assert 0 < rep["overall"]["nrmse"] < 1
    assert len(list((work / "evaluate_plots").glob("*.png"))) >= 3


def test_diagnose(wheel, work, model, dataset):
    ok(wheel.dampnet("diagnose", model, dataset, "--surrogates", "4", "--json", "diagnose.json",
                     "--report", "diagnose_report", cwd=work))
    assert json.loads((work / "diagnose.json").read_text())["candidates"]
    assert (work / "diagnose_report" / "index.html").is_file()


def test_compare(wheel, work, model, dataset):
    out = ok(wheel.dampnet("compare", model, model, dataset, "--json", "compare.json", cwd=work))
    assert "NRMSE change: +0.0 %" in out
    assert json.loads((work / "compare.json").read_text())["overall"]["nrmse_change_pct"] == 0


def test_simulate(wheel, work, model):
    ok(wheel.dampnet("simulate", model, "--road", "impulse", "--out", "simulate_out", cwd=work))
    assert json.loads((work / "simulate_out" / "metrics.json").read_text())["metrics"]["acc_rms_m_s2"] > 0
    assert (work / "simulate_out" / "run.npz").is_file()


def test_plan_tests(wheel, work, model):
    """plan-tests from the wheel: the envelope beside the trained model, a built-in case, the plan
    the installed rig reads back."""
    out = ok(wheel.dampnet("plan-tests", model, "impulse:low", "--budget", "2", "--out", "plan.json",
                           "--table", "plan.csv", cwd=work))
    assert "P01" in out
    tests = json.loads((work / "plan.json").read_text())["tests"]
    assert 1 <= len(tests) <= 2
    ok(wheel.dampnet("rig", "planned", "--plan", "plan.json", "--no-progress", cwd=work))
    assert (work / "planned" / "manifest.csv").is_file()


def test_sweep(wheel, work):
    """A two-cell simulation sweep from the wheel, on its embedded Dask cluster."""
    (work / "sweep.toml").write_text("[simulation]\nmodels = ['default', 'linear:1800']\nroads = ['bump']\n"
                                     "controllers = ['passive_low']\n")
    ok(wheel.dampnet("sweep", "sweep.toml", "--out", "sweep_out", "--workers", "1", "--quiet", cwd=work))
    rows = (work / "sweep_out" / "results.csv").read_text().splitlines()
    assert len(rows) == 3 and "time_outside_training_data" in rows[0]


def test_vehicle(wheel, work, model):
    """The full vehicle from the wheel: fullcar.hpp's runtime, the lane change and its plot."""
    out = ok(wheel.dampnet("vehicle", model, "--test", "dlc", "--speed", "80", "--out", "vehicle_out", cwd=work))
    assert "cones hit" in out
    metrics = json.loads((work / "vehicle_out" / "metrics.json").read_text())["metrics"]
    assert metrics["a_y_peak_m_s2"] > 2.0
    assert (work / "vehicle_out" / "vehicle.png").is_file()


def test_export_fmu_and_onnx(wheel, work, model):
    """The FMU's sources (fmu_src/) come with the wheel and compile into an FMU there."""
    out = ok(wheel.dampnet("export", model, "--fmu", "damper.fmu", "--onnx", "damper.onnx", cwd=work))
    assert "FMI 2.0 FMU dampnet_damper" in out and "ONNX opset 17" in out
    with zipfile.ZipFile(work / "damper.fmu") as z:
        assert "binaries/linux64/dampnet_damper.so" in z.namelist()
    out = ok(wheel.dampnet("export", model, "--fmu", "damper3.fmu", "--fmi", "3", cwd=work))
    assert "FMI 3.0 FMU dampnet_damper" in out
    with zipfile.ZipFile(work / "damper3.fmu") as z:  # fmi3/ headers and buildDescription.xml from fmu_src/
        assert {"binaries/x86_64-linux/dampnet_damper.so", "sources/buildDescription.xml",
                "sources/fmi3Functions.h"} <= set(z.namelist())


def test_study(wheel, work, model):
    ok(wheel.dampnet("study", model, "--quick", "--no-plots", "--out", "study_out", cwd=work))
    assert json.loads((work / "study_out" / "study.json").read_text())["skyhook"]


def test_iri(wheel, work):
    rows = ["distance_m,elevation_m"] + [f"{0.25 * i:g},{0.005 * (i % 8 == 0):g}" for i in range(801)]
    (work / "profile.csv").write_text("\n".join(rows) + "\n")
    out = ok(wheel.dampnet("iri", "profile.csv", cwd=work))
    assert "IRI" in out and "m/km" in out


def test_bench_quick(wheel, work):
    """The default model (model.json, for the Python rows, and the header the C++ harness is
    compiled with) and the harness sources come from the wheel: this run stopped with
    'dn_model_default.json not found' before CMake installed the JSON."""
    proc = wheel.dampnet("bench", "--quick", "--calls", "5000", "--py-calls", "1000", "--sim-steps", "5000",
                         "--json", "bench.json", cwd=work)
    assert proc.returncode in (0, 1), proc.stderr[-3000:]  # 1: the budget missed on a busy machine
    assert "HIL budget" in proc.stdout and "DIFFERENT MODEL" not in proc.stdout
    res = json.loads((work / "bench.json").read_text())
    assert res["python"]["header_model_id"] == res["python"]["model_id"]


def test_embedded_firmware_from_the_wheel(wheel, work):
    """The folder `dampnet export DEFAULT --target cortex-m4` writes from the wheel (the sources
    CMake installs into the package) builds with its own CMakeLists.txt and toolchain file, and
    QEMU runs its example firmware (bench/firmware_lab.py, the source tree's lab): the forces are
    the host's, the quarter car the host loop's. The lab itself is not in the wheel: no installed
    module runs QEMU."""
    import numpy as np

    import firmware_lab as emb
    from dampnet.modeldir import load_model

    why = emb.toolchain_missing()
    if why:
        pytest.fail(why, pytrace=False)
    default = wheel.site / "dampnet" / "include" / "dn_model_default.json"  # the wheel's default model
    ok(wheel.dampnet("export", default, "--target", "cortex-m4", "--out", "firmware_m4_folder", cwd=work))
    bdir = emb.build_folder("cortex-m4", work / "firmware_m4_folder", work / "firmware_m4")
    out = emb.parse_output(emb.run(emb.firmware_path(bdir), "cortex-m4"))
    assert out.cpu == "cortex-m4" and out.part == 2 and out.errors == 0
    model = load_model(ROOT / "export" / "dn_model_default.json")
    vectors = emb.make_vectors(model, n_x=16, seconds=1.0)  # export_target's default inputs and road
    y, status = emb.host_forces(model, vectors.x)
    assert len(out.forces) == 16 and np.max(np.abs(out.forces - y)) <= 1e-5 * 2.0 / model.out_gain
    np.testing.assert_array_equal(out.status, status)
    assert emb.loop_vs_host(model, vectors.road, out)["within"]
    with zipfile.ZipFile(wheel.wheel) as z:
        runs_qemu = [n for n in z.namelist() if n.endswith(".py") and b'["qemu-system-arm"' in z.read(n)]
    assert runs_qemu == []


def test_compare_algorithms(wheel, work, dataset):
    ok(wheel.dampnet("compare-algorithms", dataset, "--algorithms", "lm,scg", "--max-epochs", "5",
                     "--decimate", "4", "--json", "algorithms.json", "--quiet", cwd=work))
    rows = json.loads((work / "algorithms.json").read_text())["rows"]
    assert [r["algorithm"] for r in rows] == ["lm", "scg"]
    assert all(0 < r["nrmse_test"] < 1 and 1 <= r["epochs"] <= 5 for r in rows), rows


def test_export_header_and_target(wheel, work, model):
    """The header and the microcontroller folder from the wheel (the folder's sources are the
    package's own copy); the folder is not built here (test_embedded_firmware_from_the_wheel
    builds the default one)."""
    ok(wheel.dampnet("export", model, "--header", "m.h", cwd=work))
    assert "#define" in (work / "m.h").read_text()
    ok(wheel.dampnet("export", model, "--target", "cortex-m4", "--out", "m4_folder", cwd=work))
    assert {"model.h", "CMakeLists.txt"} <= {p.name for p in (work / "m4_folder").iterdir()}


def test_every_command_is_run_from_the_wheel():
    """Each of the CLI's commands has a run from the wheel in this file (demo: test_demo.py)."""
    import argparse

    from dampnet.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    text = Path(__file__).read_text()
    missing = [c for c in sub.choices if c != "demo" and f'wheel.dampnet("{c}"' not in text]
    assert not missing, f"commands never run from the wheel: {missing}"
