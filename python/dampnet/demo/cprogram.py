"""Stage 5 of the demo: compile the C controller program against the exported header and
the dampnet C library, run it on held-out samples, and compare with Python."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np

from dampnet import _core, paths
from dampnet.data import DynoTest

SOURCE = Path(__file__).resolve().parent / "controller.c"


def compile_controller(model_dir: Path, out_dir: Path) -> Path:
    """Build controller.c with the model's model.h; returns the executable."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if not cc:
        raise RuntimeError("no C compiler found (cc/gcc): install gcc to run the C program stage")
    out_dir.mkdir(parents=True, exist_ok=True)
    shutil.copy2(SOURCE, out_dir / "controller.c")
    exe = out_dir / "controller"
    lib = paths.shared_library()
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror",
           *[f"-I{d}" for d in paths.include_dirs()], f"-I{model_dir}", str(out_dir / "controller.c"),
           "-o", str(exe), str(lib), f"-Wl,-rpath,{lib.parent}", "-lm"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"compiling the C program failed:\n{' '.join(cmd)}\n{proc.stderr}")
    (out_dir / "build_command.txt").write_text(" ".join(cmd) + "\n")
    return exe


#: the fields of dn_damper_input controller.c reads per line, in struct order: the quantities a
#: model may read (DN_DAMPER_INPUT_FIELDS' roles QTY and QTY_OPT: the fields the runtime's
#: features read, the damper's states among them; x v a u u_lag temperature v_lag z_fric ...)
ROW_FIELDS = tuple(f for f in _core.DAMPER_INPUT_FIELDS if f in set(_core.FEATURE_INPUTS.values()))


def controller_inputs(model, test: DynoTest, n: int) -> np.ndarray:
    """Rows of ROW_FIELDS (dn_damper_input's quantities) for the first n samples of a test, as
    the loop would feed them: each field from the model's feature that reads it
    (dampnet.features' registry), else its base feature; a damper state the model does not
    use takes its steady value (dampnet.features.damper_states: a lag its source, the Dahl
    state sgn(v))."""
    from dampnet.features import FEATURES, damper_states, feature_matrix

    base = {f.field: f.name for f in FEATURES.values() if f.state is None}
    base["u"] = test.control_name  # voltage or current

    def column(name):
        if name == "temperature" and "temperature" not in test.channels:
            return np.full(len(test), 20.0)
        return feature_matrix([test], [name], model.feature_params)[:, 0]

    cols = {fld: column(nm) for fld, nm in base.items()}
    for fld in ROW_FIELDS:
        if fld in cols:
            continue
        used = [f for f in model.features if FEATURES[f].field == fld]
        if used:
            cols[fld] = column(used[0])
        else:  # not used by the model: the state's steady value
            state, _param = damper_states()[fld]
            cols[fld] = np.asarray(state.steady(cols), dtype=np.float64)
    return np.column_stack([cols[fld] for fld in ROW_FIELDS])[:n]


def run_controller(exe: Path, rows: np.ndarray) -> np.ndarray:
    text = "\n".join(" ".join(f"{v:.17g}" for v in r) for r in rows) + "\n"
    proc = subprocess.run([str(exe)], input=text, capture_output=True, text=True, timeout=120)
    if proc.returncode != 0:
        raise RuntimeError(f"the C program failed: {proc.stderr.strip()}")
    return np.array(proc.stdout.split(), dtype=np.float64)


def check_against_python(model, model_dir: Path, tests: list[DynoTest], out_dir: Path,
                         n_per_test: int = 2000) -> dict:
    """Compile, run on held-out samples, and compare with predict_force; returns the figures."""
    from dampnet.predict import predict_force

    exe = compile_controller(model_dir, out_dir)
    worst, n_total, scale = 0.0, 0, 0.0
    for t in tests:
        rows = controller_inputs(model, t, n_per_test)
        c_force = run_controller(exe, rows)
        py_force = predict_force(model, t)[: len(rows)]
        worst = max(worst, float(np.max(np.abs(c_force - py_force))))
        scale = max(scale, float(np.ptp(py_force)))
        n_total += len(rows)
    tol = 1e-9 * max(scale, 1.0)  # double precision on both sides: rounding only
    return {"samples": n_total, "tests": len(tests), "max_abs_diff_n": worst,
            "force_range_n": scale, "tolerance_n": tol, "match": bool(worst <= tol),
            "source": str(out_dir / "controller.c"), "executable": str(exe)}
