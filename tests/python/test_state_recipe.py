"""dn_xmacro.h's recipe for a new stateful feature, applied as a developer applies it (issue 52
item 5; issue 30 "A recipe that is true"): the recipe comment's four example rows, read from the
comment itself, appended to their lists in a copy of the tree (tests/python/recipe_tree.py) and
nothing else edited; the copy's dampnet._core rebuilt from it, its typed stub rewritten by the
command the recipe names, its own registry tests passed, and the feature run through every host,
each equal to a plain numpy reference.

The recipe's example: "displacement_lag", a first-order lag (dynamics lag_ramp) of the
displacement x with time constant "displacement_lag_tau_s", kept in dn_damper_input.x_lag and the
damper state DN_DS_X_LAG. The damper is a 2-4-1 tanh MLP on ("velocity", "displacement_lag")
with fixed weights (tau = 20 ms); its force depends on the lag (a lagged spring of ~15 kN/m
beside ~1.5 kN s/m of damping), so a wrong or missing state changes the force.

0. The copy (python): its _core knows the feature, its stub check fails naming the recipe's
   command until that command is run, then its registry tests pass (test_damper_state_registry,
   test_core_stub with mypy's stubtest, test_feature_registry: each lists the features and states
   from the registries, so the new ones are checked as the built-in ones are).
1. Quarter car (dn_loop_*; tests/cpp/recipe/recipe_hosts.c with the copy's C ABI sources, RK4
   with per-stage evaluations) on a sine + step road: the reported feature and the state
   block's x_lag (dn_loop_get_state: the block's last value) equal the exact first-order-hold
   recursion of the reported x, and the force the numpy MLP on (v, x_lag).
2. Full car (dn_fullcar_*, four corners on different roads): the same per corner, x_lag read
   at each corner's block end (DN_FULLCAR_CORNER_DAMPER + DN_DS_X_LAG).
3. Damper FMU (FMI 2), exported by the copy's dampnet (its registries, its cpp/fmu):
   co-simulation equals the recursion and the MLP; model exchange, integrated here by RK4
   through fmi2SetContinuousStates / fmi2GetDerivatives, equals the ODE's closed-form solution.
4. Cortex-M4F firmware (the copy's cpp/embedded, arm-none-eabi) in QEMU: its printed loop state,
   which now ends with x_lag, equals the host quarter car of the same model and configuration
   (recipe_hosts fwloop) within the float loop's tolerance.

Tolerances (each with its reason at its assert): x_lag 1e-12 of its peak (the same recursion in
double, only the coefficients' last-bit rounding differs), force 1e-9 of its peak (the runtime
folds the mapminmax scalings into the weights: a different rounding order, ~1e-15), model
exchange 1e-9 (RK4 at h = dt / 10 = tau / 200: global error ~ (h / tau)^4 ~ 6e-10), firmware
dampnet.export.mcu.HOST_TOLERANCE = 1e-4 of each state's peak (float loop; test_embedded's).
Everything goes to build/tests-recipe/ (the copy, its module's and the firmware's builds, cached
there between runs: only what changed is rebuilt). Cost: about 2 min of CPU from nothing (the
module's unity build about 25 s of it, the copy's tests 30 s), 20 s when cached."""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import needs
import recipe_tree
from cbuild import BUILD, ROOT

RECIPE = ROOT / "tests" / "cpp" / "recipe"
XMACRO = Path("cpp") / "include" / "dampnet" / "dn_xmacro.h"
WORK = BUILD / "tests-recipe"
TREE = WORK / "tree"        # the copy of the tree the recipe is applied to

TAU = 0.02      # displacement_lag_tau_s [s]
DT = 1e-3       # the vehicles' default step [s]
FEATURES = ("velocity", "displacement_lag")
PARAM = "displacement_lag_tau_s"

# The damper: mapminmax scaling as dn_mlp_desc defines it, x_s = (x - in_offset) in_gain + in_ymin
# after clamping to [sat_lo, sat_hi], y = (y_s - out_ymin) / out_gain + out_offset.
W1 = np.array([[1.2, 0.8], [-0.7, 0.5], [0.4, 0.3], [0.9, 0.6]])
B1 = np.array([0.1, -0.2, 0.05, 0.3])
W_OUT = np.array([0.6, -0.4, 0.5, 0.3])
B_OUT = float(-W_OUT @ np.tanh(B1))  # no force at rest (v = 0, x_lag = 0)
SAT_LO, SAT_HI = np.array([-2.0, -0.08]), np.array([2.0, 0.08])
IN_OFFSET, IN_GAIN, IN_YMIN = SAT_LO, 2.0 / (SAT_HI - SAT_LO), -1.0
OUT_OFFSET, OUT_GAIN, OUT_YMIN = -2000.0, 1.0 / 2000.0, -1.0


def mlp_force(v, x_lag) -> np.ndarray:
    """The damper's force [N] in numpy, straight from dn_mlp_desc's definition."""
    x = np.clip(np.column_stack([v, x_lag]), SAT_LO, SAT_HI)
    xs = (x - IN_OFFSET) * IN_GAIN + IN_YMIN
    ys = np.tanh(xs @ W1.T + B1) @ W_OUT + B_OUT
    return (ys - OUT_YMIN) / OUT_GAIN + OUT_OFFSET


def lag_reference(x: np.ndarray, dt: float = DT, tau: float = TAU) -> np.ndarray:
    """The lag of x sampled every dt, x a ramp between samples (exact first-order hold), from
    rest (x_lag[0] = x[0]): x_lag[k+1] = A x_lag[k] + (1 - A) x[k] + (x[k+1] - x[k]) (1 - tau (1 - A) / dt)."""
    a = np.exp(-dt / tau)
    g = 1.0 - tau * (1.0 - a) / dt
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(len(x) - 1):
        y[k + 1] = a * y[k] + (1.0 - a) * x[k] + (x[k + 1] - x[k]) * g
    return y


def c_array(values) -> str:
    return "(const double[]){" + ", ".join(repr(float(v)) for v in np.ravel(values)) + "}"


def model_header() -> str:
    """recipe_model.h: the damper for recipe_hosts.c (RECIPE_*) and for the firmware (DN_FW_*:
    cpp/embedded/firmware.c's model macros, the header naming itself as DN_FW_MODEL_HEADER).
    Macros only (compound literals), so it can be force-included into every C file."""
    desc = ", ".join([
        "2", "4", "0", "DN_ACT_TANH", c_array(W1), c_array(B1), "NULL", "NULL", c_array(W_OUT),
        c_array([B_OUT]), c_array(IN_OFFSET), c_array(IN_GAIN), repr(IN_YMIN), repr(OUT_OFFSET),
        repr(OUT_GAIN), repr(OUT_YMIN), c_array(SAT_LO), c_array(SAT_HI)])
    return "\n".join([
        "/* Generated by tests/python/test_state_recipe.py: the recipe test's damper. */",
        "#ifndef RECIPE_MODEL_H", "#define RECIPE_MODEL_H",
        f"#define RECIPE_DESC_INIT {{{desc}}}",
        '#define RECIPE_FEATURE_NAMES ((const char* const[]){"velocity", "displacement_lag"})',
        "#define RECIPE_N_INPUTS 2",
        f'#define RECIPE_PARAM_NAMES ((const char* const[]){{"{PARAM}"}})',
        f"#define RECIPE_PARAM_VALUES ((const double[]){{{TAU!r}}})",
        "#define RECIPE_N_PARAMS 1",
        '#define DN_FW_MODEL_HEADER "recipe_model.h"',
        "#define DN_FW_DESC_INIT RECIPE_DESC_INIT",
        "#define DN_FW_FEATURE_NAMES RECIPE_FEATURE_NAMES",
        "#define DN_FW_N_INPUTS RECIPE_N_INPUTS",
        "#define DN_FW_PARAM_NAMES RECIPE_PARAM_NAMES",
        "#define DN_FW_PARAM_VALUES RECIPE_PARAM_VALUES",
        "#define DN_FW_N_PARAMS RECIPE_N_PARAMS",
        "#endif", ""])


# ---- the recipe applied to a copy of the tree ----

#: the recipe's example, as dampnet._core's registries must hold it once applied
EXAMPLE_ROWS = [
    ("DN_FEATURE_PARAM_LIST", 'X(DN_FPARAM_DISPLACEMENT_LAG_TAU_S, "displacement_lag_tau_s", '
                              '"time constant of displacement_lag [s], > 0")'),
    ("DN_DAMPER_INPUT_FIELDS", 'X(dn_real, x_lag, QTY_OPT, "relative displacement after a first-order lag [m]")'),
    ("DN_FEATURE_LIST", 'X(DN_FEAT_DISPLACEMENT_LAG, "displacement_lag", x_lag, DN_FPARAM_DISPLACEMENT_LAG_TAU_S)'),
    ("DN_DAMPER_STATE_LIST", 'X(DN_DS_X_LAG, x_lag, "m", DN_DYN_LAG_RAMP, x, DN_FPARAM_DISPLACEMENT_LAG_TAU_S, '
                             '"relative displacement after displacement_lag\'s lag")'),
]


def _write_if_changed(path: Path, text: str) -> None:
    """Write text unless the file holds it already (the cached builds stay valid)."""
    if not path.is_file() or path.read_text() != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_the_recipe_comment_gives_its_example_rows():
    """The rows read from dn_xmacro.h's comment are the example, one per step, in the lists the
    steps name; appending them changes the header by those four lines only. Cost: 0.01 s."""
    text = (ROOT / XMACRO).read_text()
    rows = recipe_tree.state_recipe_rows(text)
    assert rows == EXAMPLE_ROWS
    edited = recipe_tree.apply_rows(text, rows)
    def lines(t):  # continuation backslashes aside: appending a row puts one on the line before it
        return [ln.rstrip(" \\").strip() for ln in t.split("\n")]

    original = lines(text)
    assert [ln for ln in lines(edited) if ln not in original] == [r for _, r in rows]
    assert len(lines(edited)) == len(original) + len(rows)


@pytest.fixture(scope="module")
def tree() -> Path:
    """The copy of the tree with the recipe applied: every file as in this tree (copied only when
    it differs, so the copy's builds stay cached), dn_xmacro.h with the recipe's rows appended."""
    staging = WORK / "staging"
    shutil.rmtree(staging, ignore_errors=True)
    recipe_tree.copy_tree(staging)
    header = staging / XMACRO
    header.write_text(recipe_tree.apply_rows(header.read_text(), recipe_tree.state_recipe_rows(header.read_text())))
    for src in (p for p in staging.rglob("*") if p.is_file()):
        dst = TREE / src.relative_to(staging)
        if not dst.is_file() or dst.read_bytes() != src.read_bytes():
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
    shutil.rmtree(staging)
    return TREE


@pytest.fixture(scope="module")
def copy_env(tree) -> recipe_tree.CopyEnv:
    """The copy's dampnet._core built from its edited header, and a Python that imports the copy."""
    needs.need_tool("cmake")
    recipe_tree.build_core(tree, WORK / "core-build.log")
    venv = WORK / "venv"
    shutil.rmtree(venv, ignore_errors=True)
    return recipe_tree.CopyEnv.make(tree, venv)


@pytest.mark.slow(reason="the recipe's rebuild is part of the recipe: the copy's dampnet._core built from its edited "
                         "header (about 25 s of CPU at -O0 as a unity build, cached between runs) and the copy's registry tests (40 s)")
def test_the_copy_knows_the_feature_and_passes_its_registry_tests(copy_env):
    """The recipe's rebuild gives the copy's _core the feature, its parameter, field and state;
    its stub check fails naming the command the recipe gives; after that command, the copy's
    registry tests pass. Cost: the module's build (about 25 s of CPU, cached after) and 30 s."""
    proc = copy_env.run("-c", "from dampnet import _core, features; import json; print(json.dumps(["
                        "_core.FEATURE_INPUTS.get('displacement_lag'), _core.FEATURE_PARAMS.get('displacement_lag'),"
                        "list(_core.DAMPER_STATES)[-1], list(_core.DAMPER_INPUT_FIELDS)[-1], "
                        "'displacement_lag' in features.FEATURES, _core.__file__]))")
    assert proc.returncode == 0, proc.stderr
    field, param, state, input_field, in_python, core_file = __import__("json").loads(proc.stdout)
    assert Path(core_file).is_relative_to(copy_env.copy), core_file  # the copy's module, not this tree's
    assert (field, param, state, input_field, in_python) == ("x_lag", PARAM, "x_lag", "x_lag", True)
    # the shipped stub is behind the new registries: the check names the recipe's command
    stub_check = ("tests/python/test_core_stub.py::test_the_generated_parts_of_the_stub_are_up_to_date",)
    before = copy_env.run("-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", *stub_check)
    assert before.returncode == 1 and "run `python tests/python/core_stub.py`" in before.stdout, before.stdout[-3000:]
    rewrite = copy_env.run("tests/python/core_stub.py")
    assert rewrite.returncode == 0, rewrite.stdout + rewrite.stderr
    stub = (copy_env.copy / "python" / "dampnet" / "_core.pyi").read_text()
    assert "    x_lag: float  # relative displacement after a first-order lag [m]" in stub
    # (test_core_stub's check that stubtest catches a missing name tests stubtest, not the recipe)
    after = copy_env.run("-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
                         "tests/python/test_damper_state_registry.py", "tests/python/test_core_stub.py",
                         "tests/python/test_feature_registry.py", "-k", "not a_name_missing_from_the_stub",
                         timeout=900)
    assert after.returncode == 0, after.stdout[-6000:] + after.stderr[-2000:]
    print(after.stdout.strip().splitlines()[-1])


# ---- (1), (2): the quarter car and the full car through the C ABI ----

LIB_SOURCES = ("c_api_common.cpp", "c_api_mlp.cpp", "c_api_loop.cpp", "c_api_fullcar.cpp")


def _compile_all(jobs: list[list[str]]) -> None:
    procs = [(cmd, subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)) for cmd in jobs]
    failed = []
    for cmd, p in procs:
        out, err = p.communicate(timeout=600)
        if p.returncode != 0:
            failed.append(f"{' '.join(cmd)}\n{err[-4000:]}")
    assert not failed, "compiling the copy with the recipe applied failed:\n" + "\n".join(failed)


@pytest.fixture(scope="module")
def hosts(tree) -> Path:
    """recipe_hosts: recipe_hosts.c (C99) and the copy's C ABI sources (C++17, the library's
    flags: DN_STATIC, -fno-math-errno), against the copy's headers."""
    gxx, gcc = needs.need_tool("g++"), needs.need_tool("gcc")
    WORK.mkdir(parents=True, exist_ok=True)
    (WORK / "recipe_model.h").write_text(model_header())
    inc = [f"-I{tree / 'cpp' / 'include'}", "-DDN_STATIC"]
    jobs = [[gxx, "-std=c++17", "-O2", "-fno-math-errno", "-Wall", "-Wextra", *inc, "-c", str(tree / "cpp" / "src" / s),
             "-o", str(WORK / f"{s}.o")] for s in LIB_SOURCES]
    jobs.append([gcc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Werror", *inc, f"-I{WORK}", "-c",
                 str(RECIPE / "recipe_hosts.c"), "-o", str(WORK / "recipe_hosts.o")])
    _compile_all(jobs)
    exe = WORK / "recipe_hosts"
    _compile_all([[gxx, str(WORK / "recipe_hosts.o"), *[str(WORK / f"{s}.o") for s in LIB_SOURCES], "-o", str(exe),
                   "-lm"]])
    return exe


def run_hosts(exe: Path, mode: str, road: np.ndarray) -> tuple[list[int], list[list[str]]]:
    """Run recipe_hosts MODE over the road rows; (layout, the other lines split)."""
    text = "\n".join(" ".join(repr(float(v)) for v in row) for row in road) + "\n"
    proc = subprocess.run([str(exe), mode, str(len(road))], input=text, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = [ln.split() for ln in proc.stdout.splitlines()]
    assert lines[0][0] == "layout"
    return [int(v) for v in lines[0][1:]], lines[1:]


def road(n: int, amp=0.015, f1=2.0, step=0.02, t_step=0.25, amp2=0.004, f2=11.0, phase=0.0, delay=0.0):
    """A road [n, 2] at the step ends t = dt, 2 dt, ...: a 2 Hz sine, a smooth 20 mm step over
    40 ms at t_step and an 11 Hz ripple (the wheel-hop mode), 0 at t = 0 (the loop starts at rest)."""
    t = np.arange(1, n + 1) * DT - delay
    w1, w2, rise = 2 * np.pi * f1, 2 * np.pi * f2, 0.04
    u = np.clip((t - t_step) / rise, 0.0, 1.0)
    z = amp * (np.sin(w1 * t + phase) - np.sin(phase)) + step * (3 * u**2 - 2 * u**3) + amp2 * np.sin(w2 * t)
    zd = amp * w1 * np.cos(w1 * t + phase) + step * 6 * u * (1 - u) / rise + amp2 * w2 * np.cos(w2 * t)
    pre = t < 0  # a delayed corner: flat until its road arrives
    return np.column_stack([np.where(pre, 0.0, z), np.where(pre, 0.0, zd)])


def check_layout(layout: list[int]) -> None:
    """The recipe's rows are in every list: one more feature and damper state than this tree's
    (the last of the block), and the loop and full-car states grown by it (the C ABI's sizes
    agree)."""
    from dampnet import _core

    n_feat, ds_size, ds_x_lag, loop_base, loop_size, loop_size_fn, fc_size, fc_size_fn, fc_base, fc_corner, \
        fc_damper = layout
    assert n_feat == len(_core.FEATURE_NAMES) + 1
    assert ds_size == len(_core.DAMPER_STATES) + 1 and ds_x_lag == ds_size - 1
    assert loop_size == loop_size_fn == loop_base + ds_size == len(_core.STATE_NAMES) + 1
    assert fc_size == fc_size_fn == fc_base + 4 * fc_corner and fc_corner == fc_damper + ds_size


def check_lag_and_force(x, v, force, x_lag, what: str) -> dict:
    """x_lag (at each step start) and the force against the numpy reference from the reported x;
    returns the errors relative to the peaks."""
    ref = lag_reference(x)
    peak_lag, peak_f = np.abs(ref).max(), np.abs(force).max()
    err_lag = np.abs(x_lag - ref).max() / peak_lag
    f_ref = mlp_force(v, ref)
    err_f = np.abs(force - f_ref).max() / peak_f
    # x_lag is the same recursion in double; only the coefficients' rounding differs (exp vs expm1)
    assert err_lag <= 1e-12, (what, err_lag)
    # the runtime folds the scalings into the weights (another rounding order): ~1e-15
    assert err_f <= 1e-9, (what, err_f)
    # not vacuous: the car moved, the lag lags (its largest gap to x is a fifth of x's peak), no
    # input was clamped, and the force reads the lag (x in its place gives another force)
    assert np.abs(x).max() > 5e-3, what
    assert np.abs(ref - x).max() > 0.2 * np.abs(x).max(), what
    assert np.all(np.abs(v) < SAT_HI[0]) and np.all(np.abs(ref) < SAT_HI[1]), what
    assert np.abs(mlp_force(v, x) - force).max() > 0.02 * peak_f, what
    gap = float(np.abs(ref - x).max() / np.abs(x).max())
    return {"x_lag": float(err_lag), "force": float(err_f), "lag_gap_over_peak_x": gap}


def test_quarter_car_runs_the_feature(hosts):
    layout, lines = run_hosts(hosts, "loop", road(600))
    check_layout(layout)
    r = np.array([[float(v) for v in ln[1:]] for ln in lines if ln[0] == "r"])
    assert len(r) == 600
    k, x, v, force, n_feat, f0, f1, lag_after, last = r.T
    assert np.all(n_feat == 2)
    np.testing.assert_array_equal(f0, v)  # feature 0: the velocity itself
    # the state block's last value is x_lag, and the next step reports it as its feature
    np.testing.assert_array_equal(last, lag_after)
    np.testing.assert_array_equal(lag_after[:-1], f1[1:])
    errs = check_lag_and_force(x, v, force, f1, "quarter car")
    print("quarter car, error / peak:", errs)


def test_full_car_runs_the_feature(hosts):
    delay = (1.5 + 1.75) / 33.333333333333336  # the rear wheels meet the road a wheelbase later
    corners = [road(600, phase=0.0), road(600, amp=0.01, phase=0.7, amp2=0.005),
               road(600, delay=delay), road(600, amp=0.01, phase=0.7, amp2=0.005, delay=delay, step=0.03)]
    layout, lines = run_hosts(hosts, "fullcar", np.hstack(corners))
    check_layout(layout)
    c = np.array([[float(v) for v in ln[1:]] for ln in lines if ln[0] == "c"])
    assert len(c) == 4 * 600
    xs = []
    for i in range(4):
        k, corner, x, v, force, lag_after, last = c[c[:, 1] == i].T
        np.testing.assert_array_equal(last, lag_after)  # x_lag ends the corner's block
        # x_lag after step k is the lag at step k + 1's start
        ref = lag_reference(x)
        assert np.abs(lag_after[:-1] - ref[1:]).max() <= 1e-12 * np.abs(ref).max(), i
        # the force at each step start from the state there (the first: rest, x_lag = x)
        x_lag = np.concatenate([[x[0]], lag_after[:-1]])
        errs = check_lag_and_force(x, v, force, x_lag, f"full car corner {i}")
        print(f"full car corner {i}, error / peak:", errs)
        xs.append(x)
    assert np.abs(xs[0] - xs[1]).max() > 1e-3 and np.abs(xs[0] - xs[2]).max() > 1e-3  # the corners differ


# ---- (3): the damper FMU, co-simulation and model exchange ----

FMU_SCRIPT = """
import sys
import numpy as np
from dampnet.export.fmu import build, damper
from dampnet.model import MlpModel

w = np.load(sys.argv[1])
model = MlpModel(**{k: (w[k].item() if w[k].ndim == 0 else w[k]) for k in w.files if k != "tau"}, features=["velocity", "displacement_lag"],
                 units=["m/s", "m"], activation="tanh", feature_params={"displacement_lag_tau_s": float(w["tau"])})
build.package(model, damper.damper_description(model, step_s=float(sys.argv[3])), sys.argv[2], 2, None, False, True)
"""


@pytest.fixture(scope="module")
def recipe_fmu(copy_env, tmp_path_factory):
    """The damper FMU (FMI 2, both interfaces) of the recipe's model, exported by the copy's
    dampnet (its registries and its cpp/fmu: the FMU's variables come from the copy's _core)."""
    needs.need_module("fmpy")
    from fmpy import read_model_description

    work = tmp_path_factory.mktemp("recipe-fmu")
    out = work / "recipe.fmu"
    np.savez(work / "weights.npz", w1=W1, b1=B1, w_out=W_OUT, b_out=B_OUT, in_offset=IN_OFFSET, in_gain=IN_GAIN,
             out_offset=OUT_OFFSET, out_gain=OUT_GAIN, sat_lo=SAT_LO, sat_hi=SAT_HI, tau=TAU)
    (work / "export_fmu.py").write_text(FMU_SCRIPT)
    proc = copy_env.run(str(work / "export_fmu.py"), str(work / "weights.npz"), str(out), repr(DT))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    md = read_model_description(str(out))
    by_name = {sv.name: sv.valueReference for sv in md.modelVariables}
    return out, md, by_name


def _instance(path, md, cls, callbacks):
    from fmpy import extract

    ident = (md.coSimulation if cls.__name__.endswith("Slave") else md.modelExchange).modelIdentifier
    fmu = cls(guid=md.guid, unzipDirectory=extract(str(path)), modelIdentifier=ident, instanceName="recipe")
    fmu.instantiate(callbacks=callbacks)
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    return fmu


def test_fmu_describes_the_state_at_its_value_references(recipe_fmu):
    """x_lag is state k = DN_DS_X_LAG of the block: value reference 40 + k, its derivative 50 + k
    (fmu_damper.hpp), the only continuous state; the time constant a parameter."""
    from dampnet import _core

    _, md, by_name = recipe_fmu
    k = len(_core.DAMPER_STATES)  # appended after the runtime's states
    assert by_name["x_lag"] == 40 + k and by_name["der(x_lag)"] == 50 + k
    assert PARAM in by_name
    assert [sv.name for sv in md.modelVariables if sv.name in _core.DAMPER_STATES] == []
    assert md.modelExchange is not None and md.coSimulation is not None
    assert [d.variable.name for d in md.derivatives] == ["der(x_lag)"]


def test_fmu_co_simulation_equals_the_loop_recursion(recipe_fmu):
    """Communication step dt, inputs x, v at each point (the FMU's CS semantics are the loop's:
    x and v a ramp between points), force and x_lag read after setting them, as
    fmu_damper.hpp's comment states: the exact recursion and the MLP."""
    import fmi2_callbacks
    from fmpy.fmi2 import FMU2Slave

    path, md, vr = recipe_fmu
    n = 800
    t = np.arange(n) * DT
    w = 2 * np.pi * 6.0
    x = 0.02 * np.sin(w * t) + 0.01 * np.clip((t - 0.4) / 0.01, 0, 1)  # a sine and a 10 ms ramp
    v = 0.02 * w * np.cos(w * t) + np.where((t > 0.4) & (t <= 0.41), 1.0, 0.0)
    cb = fmi2_callbacks.callbacks()
    fmu = _instance(path, md, FMU2Slave, cb)
    fmu.setReal([vr["x"], vr["v"]], [x[0], v[0]])
    fmu.exitInitializationMode()
    force, x_lag = np.empty(n), np.empty(n)
    for k in range(n):
        fmu.setReal([vr["x"], vr["v"]], [x[k], v[k]])
        force[k], x_lag[k] = fmu.getReal([vr["force"], vr["x_lag"]])
        fmu.doStep(k * DT, DT)
    fmu.terminate()
    fmu.freeInstance()
    errs = check_lag_and_force(x, v, force, x_lag, "FMU co-simulation")
    print("FMU co-simulation, error / peak:", errs)


def _lag_of_sines(t, parts):
    """The exact solution of dx_lag/dt = (x - x_lag) / tau from x_lag(0) = x(0) = 0 for
    x = sum a sin(w t): a / (1 + (w tau)^2) (sin w t - w tau cos w t + w tau exp(-t / tau))."""
    y = np.zeros_like(t)
    for a, w in parts:
        r = w * TAU
        y += a / (1 + r * r) * (np.sin(w * t) - r * np.cos(w * t) + r * np.exp(-t / TAU))
    return y


def test_fmu_model_exchange_integrates_the_lag(recipe_fmu):
    """x_lag a continuous state with derivative (x - x_lag) / tau, integrated by classical RK4
    at h = dt / 10 with the inputs exact at every stage (fmi2SetTime, fmi2SetReal,
    fmi2SetContinuousStates, fmi2GetDerivatives), equals the closed-form solution for a sum of
    sines within 1e-9 of its peak (RK4's global error ~ (h / tau)^4 = (1 / 200)^4 ~ 6e-10), and
    the force read at the sample points the MLP on it."""
    import fmi2_callbacks
    from fmpy.fmi2 import FMU2Model

    path, md, vr = recipe_fmu
    parts = [(0.02, 2 * np.pi * 3.0), (0.005, 2 * np.pi * 17.0)]

    def inputs(tt):
        return (sum(a * np.sin(w * tt) for a, w in parts), sum(a * w * np.cos(w * tt) for a, w in parts))

    cb = fmi2_callbacks.callbacks()
    fmu = _instance(path, md, FMU2Model, cb)
    fmu.setReal([vr["x"], vr["v"]], list(inputs(0.0)))
    fmu.exitInitializationMode()
    fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
    n_states = 1
    states = (ctypes.c_double * n_states)()
    derivs = (ctypes.c_double * n_states)()
    fmu.fmi2GetContinuousStates(fmu.component, states, n_states)
    assert states[0] == 0.0  # rest at the initial inputs: x_lag = x(0) = 0

    def f(tt, y):
        fmu.setTime(tt)
        fmu.setReal([vr["x"], vr["v"]], list(inputs(tt)))
        states[0] = y
        fmu.fmi2SetContinuousStates(fmu.component, states, n_states)
        fmu.fmi2GetDerivatives(fmu.component, derivs, n_states)
        return derivs[0]

    sub, n = 10, 400
    h = DT / sub
    y = states[0]
    ts, ys, fs, vs = [], [], [], []
    for k in range(n + 1):
        tk = k * DT
        if k > 0:
            for j in range(sub):
                t0 = (k - 1) * DT + j * h
                k1 = f(t0, y)
                k2 = f(t0 + h / 2, y + h / 2 * k1)
                k3 = f(t0 + h / 2, y + h / 2 * k2)
                k4 = f(t0 + h, y + h * k3)
                y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                step_event, _terminate = fmu.completedIntegratorStep()
                assert not step_event  # inputs in range: the discrete outputs never change
        fmu.setTime(tk)
        xk, vk = inputs(tk)
        fmu.setReal([vr["x"], vr["v"]], [xk, vk])
        states[0] = y
        fmu.fmi2SetContinuousStates(fmu.component, states, n_states)
        force, x_lag = fmu.getReal([vr["force"], vr["x_lag"]])
        assert x_lag == y  # the state read back is the one set
        ts.append(tk), ys.append(y), fs.append(force), vs.append(vk)
    fmu.terminate()
    fmu.freeInstance()
    t, ys, fs, vs = np.array(ts), np.array(ys), np.array(fs), np.array(vs)
    ref = _lag_of_sines(t, parts)
    x = inputs(t)[0]
    err = np.abs(ys - ref).max() / np.abs(ref).max()
    assert err <= 1e-9, err  # RK4 at h = tau / 200: (h / tau)^4 ~ 6e-10 bounds its global error
    err_f = np.abs(fs - mlp_force(vs, ys)).max() / np.abs(fs).max()
    assert err_f <= 1e-9, err_f  # the force of the integrated state: the MLP's rounding only
    assert np.abs(ref - x).max() > 0.2 * np.abs(x).max()  # the lag lags
    print(f"FMU model exchange: x_lag error / peak {err:.2e} (RK4, h = {h:g} s), force error / peak {err_f:.2e}")


# ---- (4): the Cortex-M4F firmware in QEMU ----

FW_CPU = "cortex-m4"
FW_STEPS = 2000


@pytest.fixture(scope="module")
def firmware(tree):
    """The copy's cpp/embedded firmware for the Cortex-M4F (dampnet.export.mcu's configuration:
    float loop, float MLP, one evaluation per step) with the recipe's model, C files with
    -include recipe_model.h (the firmware's model macros, DN_FW_*; CMAKE_C_FLAGS after the core's
    flags that the toolchain file would otherwise give). Run in QEMU (mps2-an386)."""
    import firmware_lab as emb

    why = emb.toolchain_missing()
    if why:
        pytest.fail(why, pytrace=False)
    assert emb.mcu.ROOT == ROOT, f"dampnet imported from {emb.mcu.ROOT}, the tests are {ROOT}'s"
    WORK.mkdir(parents=True, exist_ok=True)
    _write_if_changed(WORK / "recipe_model.h", model_header())
    x = np.array([[0.1, 0.01], [-0.3, -0.02], [0.5, 0.0], [-1.5, 0.05], [0.0, -0.07]], np.float32)
    vec = WORK / "fw_vectors.h"
    # the controller recipe_hosts.c's fwloop mode sets (the runtime's on-off skyhook, 5 ms filter):
    # this test's model has no damping levels to calibrate a law on
    from dampnet.sim.vehicle import Controller

    emb.write_vectors(WORK / "fw_vectors.new.h", emb.Vectors(x=x, road=road(FW_STEPS)),
                      controller=Controller(kind="skyhook_onoff", u_tau_s=0.005))
    _write_if_changed(vec, (WORK / "fw_vectors.new.h").read_text())
    bdir = WORK / f"firmware-{FW_CPU}"
    cache = bdir / "CMakeCache.txt"
    if cache.is_file() and f"CMAKE_HOME_DIRECTORY:INTERNAL={tree}\n" not in cache.read_text():
        shutil.rmtree(bdir)  # configured from another source folder (before the copy): CMake refuses it
    core = emb.CPUS[FW_CPU]["flags"]
    flags = [f"-DCMAKE_C_FLAGS={core} -include {WORK / 'recipe_model.h'} -I{WORK}", f"-DCMAKE_CXX_FLAGS={core}"]
    gen = ["-G", "Ninja"] if shutil.which("ninja") and not (bdir / "CMakeCache.txt").is_file() else []
    # capacities for this 2-input model (the lean float kernel is compiled for exactly its
    # capacity's input count, as `dampnet export --target` sets it: dampnet.export.mcu.capacities_for)
    caps = {**emb.DEFAULT_CAPS, "INPUTS": len(FEATURES)}
    emb._run(["cmake", "-S", tree, "-B", bdir, *gen, *emb.cmake_args(FW_CPU, vec, caps=caps), *flags])
    emb._run(["cmake", "--build", bdir, "--parallel", "2", "--target", "dn_firmware"])
    out = emb.parse_output(emb.run(emb.firmware_path(bdir), FW_CPU, timeout=120))
    return x, out


def test_firmware_runs_the_feature(firmware, hosts):
    """The firmware's loop state (every 100 steps and at the end), now ending with x_lag, equals
    the host quarter car in the same configuration (recipe_hosts fwloop: float MLP, one
    evaluation per step, linearised acceleration feature, on-off skyhook through a 5 ms filter)
    within dampnet.export.mcu.HOST_TOLERANCE of each state's peak (the float loop's rounding; the
    tolerance test_embedded uses), and x_lag there is not x; the MLP part's float forces equal
    the numpy MLP within 1e-5 of the force range (test_embedded's float-kernel tolerance)."""
    from dampnet import _core
    import firmware_lab as emb

    x_in, out = firmware
    assert out.errors == 0 and out.cpu == FW_CPU
    assert emb.LOOP_CONFIG == {"damper_eval": "per_step", "accel_feature": "linear", "u_tau_s": 0.005} \
        and emb.mcu.LOOP_LAW == "skyhook_onoff", "recipe_hosts.c's fwloop mode hard-codes this configuration"
    # the MLP part: float forward on the stored inputs
    force_range = 2.0 / OUT_GAIN
    assert np.abs(out.forces.astype(float) - mlp_force(x_in[:, 0].astype(float), x_in[:, 1].astype(float))).max() \
        <= 1e-5 * force_range
    layout, lines = run_hosts(hosts, "fwloop", road(FW_STEPS))
    host = [(int(ln[1]), np.array([float(v) for v in ln[2:-1]]), float(ln[-1])) for ln in lines if ln[0] == "s"]
    assert [k for k, _, _ in out.states] == [k for k, _, _ in host] and len(host) == FW_STEPS // 100
    fw = np.array([s for _, s, _ in out.states])
    hs = np.array([s for _, s, _ in host])
    names = list(_core.STATE_NAMES) + ["x_lag"]  # the loop state with the damper block grown by x_lag
    assert fw.shape[1] == hs.shape[1] == layout[4] == len(names)
    err = {}
    for name in ("z_s", "v_s", "z_us", "v_us", "u_cmd", "x_lag"):
        i = names.index(name)
        peak = np.abs(hs[:, i]).max()
        assert peak > 0, name
        err[name] = float(np.abs(fw[:, i] - hs[:, i]).max() / peak)
    f_fw, f_host = np.array([f for _, _, f in out.states]), np.array([f for _, _, f in host])
    err["force"] = float(np.abs(f_fw - f_host).max() / np.abs(f_host).max())
    print(f"{FW_CPU} firmware vs host quarter car, error / peak:", {k: float(f"{v:.2e}") for k, v in err.items()})
    assert all(v <= emb.HOST_TOLERANCE for v in err.values()), err
    # the lag lags on the target too: x = z_s - z_us (x_static 0) against x_lag
    x = fw[:, names.index("z_s")] - fw[:, names.index("z_us")]
    lag = fw[:, names.index("x_lag")]
    assert np.abs(x).max() > 5e-3 and np.abs(lag - x).max() > 0.1 * np.abs(x).max()
