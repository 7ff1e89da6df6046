"""The firmware lab: dampnet's C library cross-built for a Cortex-M core, run under QEMU, and
its output read back (a source-tree tool, not part of the installed package; the folder a user
builds comes from `dampnet export MODEL --target CPU`, dampnet.export.mcu).

The C library builds freestanding for ``arm-none-eabi`` (``cmake/arm-none-eabi.cmake``,
``CMakePresets.json``: presets ``cortex-m4`` and ``cortex-m7``); ``cpp/embedded/`` holds a small
firmware (``firmware.c``, ``startup.c``, ``mps2.ld``) that QEMU runs on its MPS2 boards
(``mps2-an386``: Cortex-M4F, ``mps2-an500``: Cortex-M7) with semihosting output. This module

* configures and builds it from this tree (``build``) or builds an exported folder
  (``build_folder``), runs it in QEMU (``run``) and parses what it prints (``parse_output``),
* and runs the host's side of the comparison (``host_forces``, ``host_loop``, ``loop_vs_host``,
  ``host_inverse``, ``inverse_vs_host``).

    python bench/firmware_lab.py build|run [--cpu cortex-m4|cortex-m7] [--dir DIR]

Its users: bench/embedded.py (flash, RAM and instructions, bench/RESULTS.md) and the tests
(tests/python/test_embedded.py and others: the conftest puts bench/ on the path). The stored
inputs and road, the core's build options and the export folder are dampnet.export.mcu's; their
names are re-exported here for the lab's users.
"""

from __future__ import annotations

import os
import shutil
import struct
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dampnet.export import mcu
from dampnet.export.mcu import (CPUS, DEFAULT_ACCEL_FEATURES, DEFAULT_DAMPER_EVALS, DEFAULT_DAMPER_KINDS,
                                DEFAULT_KERNEL, LOOP_CONFIG, LOOP_FLOAT, PRINT_EVERY)
# re-exported for the lab's users (the tests, bench/embedded.py): the inputs and road, the
# core's build options and the export folder are dampnet.export.mcu's
from dampnet.export.mcu import (FOLDER_MARKER, FOLDER_SCHEMA, Vectors,  # noqa: F401
                                controller_kinds, make_vectors, target_defines)
from dampnet.recipes.control_laws import firmware_controller
# ... and with the firmware's controller made for the model, as `dampnet export --target` writes them
from dampnet.recipes.export_targets import export_firmware_folder as export_target  # noqa: F401
from dampnet.recipes.export_targets import write_firmware_vectors as write_vectors  # noqa: F401

ROOT = Path(__file__).resolve().parents[1]  # the source tree this lab builds

# The library's capacities for the firmware (dampnet.h "Capacities"; the presets' values): the
# thesis's 3-30-1 network (hidden layers hold multiples of 8 neurons), one hidden layer, no
# physics terms, no lookup table to speak of, and no double kernel (the damper runs the float
# MLP). `dampnet export --target` sets them from the model instead (capacities_for).
DEFAULT_CAPS = {"INPUTS": 3, "HIDDEN": 32, "HIDDEN2": 0, "TERMS": 0, "TABLE_V": 2, "TABLE_U": 1,
                "INVERSE_V": 0, "INVERSE_U": 0}
#: the cold inverse's first-iterate grid of the host's build (dn_config.h's defaults): the firmware
#: whose dn_damper_inverse is measured and checked against the host's has it too (where the model
#: turns back in u, the answer depends on where the search starts)
INVERSE_GRID_CAPS = {"INVERSE_V": 33, "INVERSE_U": 17}
DEFAULT_DOUBLE_KERNEL = 0
class EmbeddedError(RuntimeError):
    """A cross build or a QEMU run failed (the message holds the tool's output)."""


def toolchain_missing() -> str | None:
    """Why the cross build cannot run here (None: it can), naming the Debian packages of
    python/debian-packages.txt that python/env.sh installs: the cross compiler, newlib, the cross
    C++ headers (compiling ``#include <cstdint>``), QEMU and cmake."""
    need = {"arm-none-eabi-gcc": "gcc-arm-none-eabi", "arm-none-eabi-g++": "gcc-arm-none-eabi",
            "qemu-system-arm": "qemu-system-arm", "cmake": "cmake (PyPI)"}
    missing = [f"{tool} (Debian package {pkg})" for tool, pkg in need.items() if not shutil.which(tool)]
    if not missing and not _newlib_present():
        missing.append("newlib (Debian package libnewlib-arm-none-eabi)")
    if not missing and not _cross_cxx_headers_present():
        missing.append("the cross C++ headers: arm-none-eabi-g++ cannot compile #include <cstdint> "
                       "(Debian package libstdc++-arm-none-eabi-dev)")
    return ", ".join(missing) + " not installed; python/env.sh installs them" if missing else None


def _newlib_present() -> bool:
    try:
        out = subprocess.run(["arm-none-eabi-gcc", "--specs=nano.specs", "-print-file-name=libc_nano.a"],
                             capture_output=True, text=True, timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return False
    return os.path.isabs(out) and os.path.isfile(out)


def _cross_cxx_headers_present() -> bool:
    """True if arm-none-eabi-g++ preprocesses <cstdint> and <cmath> (the runtime's C++ headers)."""
    try:
        proc = subprocess.run(["arm-none-eabi-g++", "-x", "c++", "-std=c++17", "-E", "-o", os.devnull, "-"],
                              input="#include <cstdint>\n#include <cmath>\n", capture_output=True,
                              text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return False
    return proc.returncode == 0


# ---- build and run ----

def cmake_args(cpu: str, vectors: Path | None = None, build_type: str = "Release",
               caps: dict | None = None, double_kernel: int = DEFAULT_DOUBLE_KERNEL,
               fp_contract: str = "off", kernel: dict | None = None, loop_float: int | None = None,
               damper_kinds=DEFAULT_DAMPER_KINDS, controllers=None, firmware_defines=()) -> list[str]:
    """The configure options of a firmware build (what the presets of CMakePresets.json set);
    loop_float None: the core's default (LOOP_FLOAT); controllers None: the presets' laws and
    the firmware's own (controller_kinds of firmware_controller's law, LOOP_LAW's by default);
    firmware_defines: the firmware's model (model_defines; empty: the default model)."""
    if cpu not in CPUS:
        raise ValueError(f"unknown core {cpu!r}; known: {', '.join(CPUS)}")
    loop_float = LOOP_FLOAT[cpu] if loop_float is None else int(loop_float)
    args = [f"--toolchain={ROOT / 'cmake' / 'arm-none-eabi.cmake'}", f"-DDAMPNET_ARM_CPU={cpu}",
            f"-DCMAKE_BUILD_TYPE={build_type}", f"-DDAMPNET_DOUBLE_KERNEL={double_kernel}",
            f"-DDAMPNET_FP_CONTRACT={fp_contract}", f"-DDAMPNET_LOOP_FLOAT={loop_float}",
            f"-DDAMPNET_DAMPER_KINDS={';'.join(damper_kinds)}",
            f"-DDAMPNET_CONTROLLER_KINDS={';'.join(controllers or controller_kinds(mcu.LOOP_LAW))}",
            f"-DDAMPNET_ACCEL_FEATURES={';'.join(DEFAULT_ACCEL_FEATURES)}",
            f"-DDAMPNET_DAMPER_EVALS={';'.join(DEFAULT_DAMPER_EVALS)}",
            f"-DDAMPNET_FIRMWARE_DEFINITIONS={';'.join(firmware_defines)}"]
    args += [f"-DDAMPNET_CAP_{k}={v}" for k, v in (caps or DEFAULT_CAPS).items()]
    args += [f"-DDAMPNET_KERNEL_{k}={v}" for k, v in (DEFAULT_KERNEL if kernel is None else kernel).items()]
    if vectors is not None:
        args.append(f"-DDAMPNET_FIRMWARE_VECTORS={Path(vectors).resolve()}")
    else:  # CMake writes them with this interpreter (python -m dampnet.recipes.export_targets vectors)
        args.append(f"-DPython3_EXECUTABLE={sys.executable}")
    return args


def model_defines(header, model) -> list[str]:
    """The firmware's definitions (cmake_args' firmware_defines) for another model than the default:
    its header as dampnet.export.write_header writes it with the prefix dn_model (an exported
    folder's model.h), with its folded floats, its derived features' constants and its physics terms
    (the firmware then sets the loop up through a damper with them: dn_damper_add_term)."""
    header = Path(header).resolve()
    text = header.read_text()
    d = [f'DN_FW_MODEL_HEADER="{header}"', "DN_FW_DESC_INIT=DN_MODEL_DESC_INIT",
         "DN_FW_FEATURE_NAMES=dn_model_feature_names", "DN_FW_N_INPUTS=DN_MODEL_N_INPUTS"]
    if "DN_MODEL_FOLDED_INIT" in text:
        d.append("DN_FW_FOLDED_INIT=DN_MODEL_FOLDED_INIT")
    if model.feature_params:
        d += ["DN_FW_PARAM_NAMES=dn_model_feature_param_names", "DN_FW_PARAM_VALUES=dn_model_feature_param_values",
              "DN_FW_N_PARAMS=DN_MODEL_N_FEATURE_PARAMS"]
    if model.terms:
        d += ["DN_FW_N_TERMS=DN_MODEL_N_TERMS", "DN_FW_TERM_KINDS=dn_model_term_kinds",
              "DN_FW_TERM_N_PARAMS=dn_model_term_n_params", "DN_FW_TERM_PARAMS=dn_model_term_params",
              "DN_FW_TERM_WIDTH=DN_MODEL_TERM_PARAMS"]
    return d


def build(cpu: str, build_dir, vectors: Path | None = None, targets=("dn_firmware",), **options) -> Path:
    """Configure (once) and build the firmware for a core from this source tree into build_dir;
    returns build_dir."""
    build_dir = Path(build_dir)
    # an existing build keeps its generator (e.g. one of `cmake --preset cortex-m4`'s, which
    # CMake would refuse to switch)
    gen = ["-G", "Ninja"] if shutil.which("ninja") and not (build_dir / "CMakeCache.txt").is_file() else []
    _run(["cmake", "-S", ROOT, "-B", build_dir, *gen, *cmake_args(cpu, vectors, **options)])
    _run(["cmake", "--build", build_dir, "--parallel", str(os.cpu_count() or 2), "--target", *targets])
    return build_dir


def build_folder(cpu: str, folder, build_dir) -> Path:
    """Build the folder `dampnet export MODEL --target CPU --out FOLDER` wrote (with its own
    CMakeLists.txt and toolchain file: what a user of an installed dampnet builds) into
    build_dir; its example firmware is firmware_path(build_dir)."""
    folder, build_dir = Path(folder).resolve(), Path(build_dir).resolve()
    gen = ["-G", "Ninja"] if shutil.which("ninja") and not (build_dir / "CMakeCache.txt").is_file() else []
    _run(["cmake", "-S", folder, "-B", build_dir, *gen, f"--toolchain={folder / 'cmake' / 'arm-none-eabi.cmake'}",
          f"-DDAMPNET_ARM_CPU={cpu}"])
    _run(["cmake", "--build", build_dir, "--parallel", str(os.cpu_count() or 2)])
    return build_dir


def firmware_path(build_dir, name: str = "dn_firmware") -> Path:
    """The firmware `name` of a build: build_dir/cpp/embedded/NAME.elf of a source build, or the
    example firmware (build_dir/firmware.elf) of an export folder's build (build_folder)."""
    path = Path(build_dir) / "cpp" / "embedded" / f"{name}.elf"
    folder_fw = Path(build_dir) / "firmware.elf"
    return folder_fw if name == "dn_firmware" and not path.is_file() and folder_fw.is_file() else path


def run(elf, cpu: str, icount: bool = True, timeout: float = 120) -> str:
    """Run a firmware in QEMU on the core's board; returns what it printed. -icount shift=0:
    one instruction per nanosecond of virtual time, so SysTick counts instructions (the
    firmware's "calib" line gives how many per tick) and every run prints the same."""
    cmd = ["qemu-system-arm", "-M", CPUS[cpu]["machine"], "-nographic", "-monitor", "none",
           "-serial", "none", "-semihosting-config", "enable=on,target=native", "-kernel", str(elf)]
    if icount:
        cmd += ["-icount", "shift=0"]
    proc = _run(cmd, timeout=timeout)
    return proc.stdout + proc.stderr  # QEMU writes semihosting output to stderr with -nographic


def _run(cmd, timeout: float = 900) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as e:
        raise EmbeddedError(f"timed out after {timeout} s: {' '.join(map(str, cmd))}") from e
    if proc.returncode != 0:
        raise EmbeddedError(f"command failed ({proc.returncode}): {' '.join(map(str, cmd))}\n"
                            f"--- stdout\n{proc.stdout[-4000:]}\n--- stderr\n{proc.stderr[-4000:]}")
    return proc


# ---- the firmware's output ----

@dataclass
class FirmwareOutput:
    cpu: str = ""
    part: int = 0
    sizes: dict = field(default_factory=dict)       # bytes of the C ABI objects (dn_sizes.h)
    instructions_per_tick: float = 0.0              # from the calibration loop
    forces: np.ndarray | None = None                # float32 forces of the stored inputs
    status: np.ndarray | None = None
    mask: np.ndarray | None = None
    time: dict = field(default_factory=dict)        # name -> (ticks, stub ticks, n)
    stack: dict = field(default_factory=dict)       # name -> peak bytes below main's frame
    states: list = field(default_factory=list)      # (step, state[13], force) every PRINT_EVERY steps
    final: np.ndarray | None = None
    evals: int = 0
    status_or: int = 0
    errors: int = -1
    # the inverse part's cases ("inv" lines; None without it): control and force (dn_real), status,
    # evaluations (the limits' included), SysTick ticks of each call (the timer reads included)
    inv_u: np.ndarray | None = None
    inv_force: np.ndarray | None = None
    inv_status: np.ndarray | None = None
    inv_evals: np.ndarray | None = None
    inv_ticks: np.ndarray | None = None

    def instructions(self, name: str) -> float:
        """Instructions per call of a timed loop, its empty-stub loop subtracted."""
        ticks, stub, n = self.time[name]
        return (ticks - stub) * self.instructions_per_tick / n


def _f64(h: str) -> float:
    """A printed real's bits: 16 hex digits a double, 8 a float (a DN_LOOP_FLOAT build's state)."""
    return struct.unpack(">d" if len(h) == 16 else ">f", bytes.fromhex(h))[0]


def parse_output(text: str) -> FirmwareOutput:
    out = FirmwareOutput()
    forces, status, mask = [], [], []
    inv = []
    for line in text.splitlines():
        f = line.split()
        if not f:
            continue
        if f[0] == "dn_fw":
            out.cpu, out.part = f[2], int(f[4])
            out.sizes = {f[i]: int(f[i + 1]) for i in range(6, len(f) - 1, 2)}
        elif f[0] == "calib":
            out.instructions_per_tick = int(f[3]) / int(f[1])
        elif f[0] == "x":
            forces.append(struct.unpack(">f", bytes.fromhex(f[2]))[0])
            status.append(int(f[3]))
            mask.append(int(f[4]))
        elif f[0] == "time":
            out.time[f[1]] = (int(f[2]), int(f[4]), int(f[6]))
        elif f[0] == "stack":
            out.stack[f[1]] = int(f[2])
        elif f[0] in ("s", "final"):
            vals = np.array([_f64(h) for h in f[2:]])
            if f[0] == "s":
                out.states.append((int(f[1]), vals[:-1], vals[-1]))
            else:
                out.final = vals[:-1]
        elif f[0] == "loop":
            out.evals, out.status_or = int(f[2]), int(f[4])
        elif f[0] == "inv":
            inv.append((_f64(f[2]), _f64(f[3]), int(f[4]), int(f[5]), int(f[6])))
        elif f[0] == "done":
            out.errors = int(f[2])
    if forces:
        out.forces = np.array(forces, dtype=np.float32)
        out.status, out.mask = np.array(status), np.array(mask, dtype=np.uint32)
    if inv:
        u, force, st, n, t = zip(*inv)
        out.inv_u, out.inv_force = np.array(u), np.array(force)
        out.inv_status, out.inv_evals, out.inv_ticks = np.array(st), np.array(n), np.array(t)
    return out


# ---- the host's side of the comparison ----

def host_forces(model, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The host runtime's float forward (dampnet._core, the kernel the host was built with)."""
    y, st, _ = model.core().predict(np.asarray(x, np.float32).astype(np.float64), single=True)
    return y, st


def host_loop(model, road: np.ndarray, every: int = PRINT_EVERY, controller=None):
    """The host loop in the firmware's configuration (float MLP, double state) over the road:
    the state after every `every` steps, the final state and the damper evaluations. `controller`:
    a dampnet.sim.vehicle.Controller (default: the firmware's, firmware_controller)."""
    from dampnet import _core
    from dampnet.sim.quarter_car.loop import damper_from_model

    vehicle = {k: LOOP_CONFIG[k] for k in ("damper_eval", "accel_feature")}
    # as write_vectors gives the firmware, unless the caller's program sets another (a Controller)
    controller = (controller or firmware_controller(model)).core_dict()
    loop = _core.Loop(_core.LoopModel(damper_from_model(model, single=True), vehicle, controller))
    states = []
    for k, (z, v) in enumerate(road.tolist(), start=1):
        loop.step(z, v)
        if k % every == 0 or k == len(road):
            states.append((k, np.array(loop.state)))
    return states, np.array(loop.state), loop.damper_evals


#: the loop-state columns the firmware-vs-host comparison reads, by name (found in STATE_NAMES:
#: the firmware's loop state is built from the same dampnet.h)
COMPARED_STATES = ("z_s", "v_s", "z_us", "v_us", "u_cmd")
#: the firmware's state may differ from the host's double loop by this share of each state's peak
#: (the float loop's rounding: measured 1.2e-6 on the M4F)
HOST_TOLERANCE = 1e-4


def loop_vs_host(model, road: np.ndarray, out) -> dict:
    """The firmware run `out` (parse_output) against host_loop on the same road: {error_over_peak
    {state: max |fw - host| / peak}, peak, final_error_over_peak, evals (firmware, host), within
    (every error <= HOST_TOLERANCE of its peak, the same step indices and evaluation count)}."""
    from dampnet import _core

    states, final, evals = host_loop(model, road)
    idx = [_core.STATE_NAMES.index(name) for name in COMPARED_STATES]
    fw = np.array([s for _, s, _ in out.states])
    host = np.array([s for _, s in states])
    same_steps = [k for k, _, _ in out.states] == [k for k, _ in states] and fw.shape == host.shape
    peak = np.abs(host[:, idx]).max(axis=0)
    err = np.abs(fw[:, idx] - host[:, idx]).max(axis=0) if same_steps else np.full(len(idx), np.inf)
    final_err = np.abs(np.asarray(out.final)[idx] - final[idx]) / peak
    ratio = err / peak
    return {"error_over_peak": dict(zip(COMPARED_STATES, ratio.tolist())), "peak": dict(zip(COMPARED_STATES, peak.tolist())),
            "final_error_over_peak": dict(zip(COMPARED_STATES, final_err.tolist())),
            "evals": (int(out.evals), int(evals)),
            "within": bool(same_steps and np.all(peak > 0) and np.all(ratio <= HOST_TOLERANCE)
                           and np.all(final_err <= HOST_TOLERANCE) and out.evals == evals)}


def host_inverse(model, vectors) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The host runtime's inverse (dampnet._core.Damper.inverse) of the model's float neural damper
    on the vectors' inverse cases (vectors.inv, make_vectors): (u, force, status, evaluations)."""
    d = mcu.host_damper(model)
    kw = mcu.damper_inputs(vectors.inv_fields, np.asarray(vectors.inv[:, :-1], np.float32).astype(float))
    kw.pop("u")
    return d.inverse(np.asarray(vectors.inv[:, -1], np.float32).astype(float), **kw)


#: the firmware's inverse may differ from the host's by this share of the control range in u (the
#: issue's tolerance of the inverse against a brute-force search) and by this share of the force
#: range in force (the forward's, test_embedded's test_forces_equal_host_float_forward)
INVERSE_U_TOLERANCE = 1e-4
INVERSE_FORCE_TOLERANCE = 1e-5


def inverse_vs_host(model, vectors, out) -> dict:
    """The firmware's inverse part (out: parse_output) against host_inverse on the same cases:
    {n, statuses equal, u_error_over_range (max over the cases without an error), force_error_over_range,
    worst (its case), the host's and the firmware's evaluations (mean over the cases without an
    error), counts per status, within (same statuses, and errors where the host errors, u and force
    within INVERSE_U_TOLERANCE / INVERSE_FORCE_TOLERANCE)}."""
    u, force, status, evals = host_inverse(model, vectors)
    lo, hi = mcu.host_damper(model).control_range()
    u_range, force_range = hi - lo, 2.0 / model.out_gain
    same_n = out.inv_u is not None and len(out.inv_u) == len(u)
    if not same_n:
        return {"n": 0 if out.inv_u is None else len(out.inv_u), "within": False}
    ok = status >= 0
    du = np.abs(out.inv_u - u) / u_range
    df = np.abs(out.inv_force - force) / force_range
    worst = int(np.argmax(np.where(ok, du, -1.0)))
    same_status = bool(np.array_equal(out.inv_status, status))
    counts = {int(k): int(c) for k, c in zip(*np.unique(status, return_counts=True))}
    res = {"n": len(u), "statuses_equal": same_status, "host_status_counts": counts,
           "u_error_over_range": float(du[ok].max()) if ok.any() else 0.0,
           "force_error_over_range": float(df[ok].max()) if ok.any() else 0.0,
           "worst": {"case": worst, "u_host": float(u[worst]), "u_firmware": float(out.inv_u[worst]),
                     "status": int(status[worst])},
           "evals_host": float(np.mean(evals[ok])) if ok.any() else 0.0,
           "evals_firmware": float(np.mean(out.inv_evals[ok])) if ok.any() else 0.0}
    res["within"] = bool(same_status and res["u_error_over_range"] <= INVERSE_U_TOLERANCE
                         and res["force_error_over_range"] <= INVERSE_FORCE_TOLERANCE)
    return res


def main(argv=None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python bench/firmware_lab.py", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build", help="build the firmware for a core")
    b.add_argument("--cpu", choices=sorted(CPUS), default="cortex-m4")
    b.add_argument("--dir", default=None, help="build directory (default: the source tree's build/CPU)")
    r = sub.add_parser("run", help="build and run the firmware in QEMU, print its output")
    r.add_argument("--cpu", choices=sorted(CPUS), default="cortex-m4")
    r.add_argument("--dir", default=None)
    a = p.parse_args(argv)
    why = toolchain_missing()
    if why:
        print(f"dampnet: error: {why}", file=sys.stderr)
        return 2
    bdir = Path(a.dir or ROOT / "build" / a.cpu)
    try:
        build(a.cpu, bdir)
        if a.cmd == "run":
            sys.stdout.write(run(firmware_path(bdir), a.cpu))
    except (EmbeddedError, OSError, ValueError) as e:
        print(f"dampnet: error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
