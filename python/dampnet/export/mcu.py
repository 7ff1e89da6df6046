"""dampnet on a Cortex-M microcontroller: the ready-to-build folder of `dampnet export MODEL
--target cortex-m4|cortex-m7 --out DIR` (``export_target``), and the firmware's stored inputs and
road (``write_vectors``; with the controller the control-law registry makes for the model:
``python -m dampnet.recipes.export_targets vectors OUT.h``, which the source tree's
cpp/embedded/CMakeLists.txt runs).

The folder holds the model's header, the library's sources with the model's capacities and the
core's build options (``target_defines``), the toolchain file and an example firmware for QEMU's
MPS2 boards (``mps2-an386``: Cortex-M4F, ``mps2-an500``: Cortex-M7). Building and running
firmware under QEMU is a lab tool, not part of the installed package: bench/firmware_lab.py
(tests/python/test_embedded.py compares the firmware with the host runtime; bench/embedded.py
measures flash, RAM and instructions, bench/RESULTS.md).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]  # the source tree, when dampnet runs from one


def source_tree() -> bool:
    """True if dampnet runs from its source tree (a checkout, an editable install): the root
    CMakeLists.txt and cpp/embedded/ are there. An installed wheel has only what
    `dampnet export --target` needs (installed into the package by CMakeLists.txt)."""
    return (ROOT / "CMakeLists.txt").is_file() and (ROOT / "cpp" / "embedded" / "firmware.c").is_file()

# The two cores: the QEMU board that emulates each and the compiler's flags for it.
CPUS = {
    "cortex-m4": {"machine": "mps2-an386", "flags": "-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb",
                  "fpu": "single-precision (FPv4-SP): double arithmetic in software"},
    "cortex-m7": {"machine": "mps2-an500", "flags": "-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard -mthumb",
                  "fpu": "double-precision (FPv5-D16)"},
}

# The float kernel for flash (dampnet.h DN_KERNEL_SMALL, DN_KERNEL_UNROLL; the presets' values):
# one forward, compiled for the capacity's input count, two neurons per pass
# (bench/LOG.md, "On a microcontroller": the trade-off measured).
DEFAULT_KERNEL = {"SMALL": 1, "UNROLL": 2}
# Only the neural damper kind is linked (dampnet.h DN_DAMPER_KINDS): the others' code and their
# libm functions stay out of flash.
DEFAULT_DAMPER_KINDS = ("neural",)
# The acceleration-feature schemes linked (dampnet.h DN_ACCEL_FEATURES): linear (the HIL choice:
# one network evaluation per damper call) and explicit, not the implicit solve's iteration (up to
# DN_ACCEL_MAX_EVALS = 6 evaluations per call).
DEFAULT_ACCEL_FEATURES = ("linear", "explicit")
# The control laws linked (dampnet.h DN_CONTROLLER_KINDS): all but the force-tracking ones, whose
# damper inverse would add about 3.6 KB to an M4F's loop (bench/RESULTS.md, "The damper's inverse
# on the MCU"); a firmware running one of those gets it added (controller_kinds).
DEFAULT_CONTROLLER_KINDS = ("passive", "skyhook_onoff", "skyhook_continuous", "groundhook_onoff",
                            "groundhook_continuous", "external")
# The damper-evaluation schemes linked (dampnet.h DN_DAMPER_EVALS): one evaluation per step.
DEFAULT_DAMPER_EVALS = ("per_step",)
# The loop's state and arithmetic per core (dampnet.h DN_LOOP_FLOAT): float on the M4F, whose FPU
# has no double, double on the M7 (FPv5-D16 does double in hardware; the host's precision).
LOOP_FLOAT = {"cortex-m4": 1, "cortex-m7": 0}


def _name_mask(what: str, names, registry: dict) -> int:
    """The bit mask of names of one dampnet.h enum (registry: the runtime's name -> (value, doc),
    e.g. _core.DAMPER_KINDS), as the root CMakeLists.txt's dn_name_mask makes it."""
    unknown = sorted(set(names) - set(registry))
    if unknown:
        raise ValueError(f"{what} {unknown}: expected some of {', '.join(registry)}")
    return sum(1 << registry[k][0] for k in set(names))


def controller_kinds(law_kind: str | None = None) -> tuple[str, ...]:
    """The control laws a firmware build links: DEFAULT_CONTROLLER_KINDS and the law it runs
    (law_kind: a _core.CONTROLLER_KINDS name, e.g. a force-tracking law's)."""
    extra = (law_kind,) if law_kind and law_kind not in DEFAULT_CONTROLLER_KINDS else ()
    return DEFAULT_CONTROLLER_KINDS + extra


def target_defines(cpu: str, caps: dict, loop_float: int | None = None,
                   damper_kinds=DEFAULT_DAMPER_KINDS, controllers=DEFAULT_CONTROLLER_KINDS) -> list[str]:
    """The library's compile definitions for a core (what the root CMakeLists.txt derives from the
    DAMPNET_* options of a freestanding build): capacities, float MLP only, the loop's real type,
    the damper kinds, control laws (controllers: names), acceleration and evaluation schemes
    linked, code size over inlining, and the lean float kernel."""
    from dampnet import _core

    lf = LOOP_FLOAT[cpu] if loop_float is None else int(loop_float)
    return ([f"DN_CAP_{k}={v}" for k, v in caps.items()]
            + ["DN_DOUBLE_KERNEL=0", f"DN_LOOP_FLOAT={lf}",
               f"DN_DAMPER_KINDS={_name_mask('damper kinds', damper_kinds, _core.DAMPER_KINDS)}",
               f"DN_CONTROLLER_KINDS={_name_mask('control laws', controllers, _core.CONTROLLER_KINDS)}",
               f"DN_ACCEL_FEATURES={_name_mask('acceleration features', DEFAULT_ACCEL_FEATURES, _core.ACCEL_FEATURES)}",
               f"DN_DAMPER_EVALS={_name_mask('damper evaluations', DEFAULT_DAMPER_EVALS, _core.DAMPER_EVALS)}",
               "DN_SMALL_CODE=1"]
            + [f"DN_KERNEL_{k}={v}" for k, v in DEFAULT_KERNEL.items()])

# The quarter car the firmware runs (and the host comparison with it): the HIL configuration
# of `dampnet bench` (one damper evaluation per RK4 step, the linearised acceleration feature,
# the float MLP), thesis Table 5 vehicle, on-off skyhook through a 5 ms command filter.
LOOP_CONFIG = {"damper_eval": "per_step", "accel_feature": "linear", "u_tau_s": 0.005}
#: the firmware's control law, by its registered name: dampnet.recipes.control_laws.firmware_controller
#: makes it for the exported model as every front end makes a law (calibrated on its own low and high
#: damping controls), and the callers of write_vectors and export_target pass it in
LOOP_LAW = "skyhook_onoff"
ROAD_SPEED = 18.4      # [m/s]: the thesis rough road (184 m) in 10 s
ROAD_SECONDS = 10.0
DT = 0.001             # the vehicle's default step [s]
N_INPUTS_DEFAULT = 1000
PRINT_EVERY = 100      # the firmware prints the state every this many steps
N_INVERSE_DEFAULT = 300  # cases of the damper's inverse the firmware runs (make_vectors)


# ---- the stored inputs and road ----

@dataclass
class Vectors:
    x: np.ndarray          # [n, n_inputs] float32: the MLP's inputs
    road: np.ndarray       # [n_steps, 2] float64: road [m] and its rate [m/s] at each step's end
    #: the damper inverse's cases (dn_damper_inverse), [n_inv, len(inv_fields) + 2] float32: the
    #: dn_damper_input fields named by inv_fields (those the model reads but u), u (read by the
    #: forward the inverse is timed against), the demanded force [N]; None: no inverse part
    inv: np.ndarray | None = None
    inv_fields: tuple[str, ...] = ()


def make_vectors(model, n_x: int = N_INPUTS_DEFAULT, seconds: float = ROAD_SECONDS, seed: int = 0,
                 road=None, n_inv: int = N_INVERSE_DEFAULT) -> Vectors:
    """Inputs in and out of the model's saturation range (the first half uniform within it, the
    second over the range widened by half its width on each side, so most of those clamp an
    input), six non-finite ones (NaN, +-Inf in rows 0..5), a road (a dampnet.sim.roads Road,
    default the thesis's rough road) at ROAD_SPEED, shifted to start at 0 (the loop starts at rest),
    and n_inv cases of the damper's inverse (inverse_vectors; 0: none, and the firmware built on
    these vectors has no inverse part)."""
    from dampnet.sim import roads

    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(model.sat_lo, float), np.asarray(model.sat_hi, float)
    span = hi - lo
    half = n_x // 2
    x = np.concatenate([rng.uniform(lo, hi, size=(half, len(lo))),
                        rng.uniform(lo - 0.5 * span, hi + 0.5 * span, size=(n_x - half, len(lo)))])
    x = x.astype(np.float32)
    for k, v in enumerate([np.nan, np.nan, np.nan, np.inf, -np.inf, np.inf]):
        if k < n_x:
            x[k, k % len(lo)] = v
    r = (road or roads.thesis_rough_road(seed=0)).sample(DT, speed=ROAD_SPEED)
    n_steps = int(round(seconds / DT))
    z = np.asarray(r.z, float)[1:n_steps + 1] - float(r.z[0])
    zdot = np.asarray(r.zdot, float)[1:n_steps + 1]
    inv, inv_fields = inverse_vectors(model, n_inv, seed=seed) if n_inv > 0 else (None, ())
    return Vectors(x=x, road=np.column_stack([z, zdot]), inv=inv, inv_fields=inv_fields)


def inverse_fields(model) -> tuple[str, ...]:
    """The dn_damper_input fields the model's features read (dampnet._core.FEATURE_INPUTS), u
    excluded, in feature order: what a case of the inverse stores besides u and the demand."""
    from dampnet import _core

    out: list[str] = []
    for f in model.features:
        field = _core.FEATURE_INPUTS[f]
        if field != "u" and field not in out:
            out.append(field)
    return tuple(out)


def host_damper(model):
    """The host runtime's float neural damper of the model (dampnet._core.Damper, DN_PRECISION_FLOAT
    MLP): what the firmware's inverse part builds with dn_damper_init_neural."""
    from dampnet.sim.quarter_car.loop import damper_from_model

    return damper_from_model(model, single=True)


def damper_inputs(fields, values: np.ndarray) -> dict[str, np.ndarray]:
    """Keyword arrays of dampnet._core.Damper.forces / .inverse for the columns `values` [n, k] of
    the named fields, every other field 0 (as the firmware's zeroed dn_damper_input)."""
    from dampnet import _core

    n = len(values)
    kw = {name: np.zeros(n) for name in _core.DAMPER_INPUT_FIELDS if name not in ("t", "dt", "stage")}
    for j, name in enumerate(fields):
        kw[name] = np.asarray(values[:, j], float)
    return kw


def inverse_vectors(model, n: int = N_INVERSE_DEFAULT, seed: int = 0) -> tuple[np.ndarray, tuple[str, ...]]:
    """Cases of the damper's inverse (dn_damper_inverse): (rows [n, k + 2] float32, fields): the k
    input fields the model reads (inverse_fields: half uniform within the model's saturation range
    of the feature reading each, half over it widened by half its width on each side), u uniform
    over the control range (only the forward it is timed against reads it), and a demanded force
    between and beyond the host float damper's forces at the two control limits F(u_min), F(u_max)
    (a share t of the way from one to the other: 60 % reachable, t in [0.02, 0.98]; 40 % beyond
    either, t in [-0.5, -0.02] or [1.02, 1.5]), kept at least 2 % of |F(u_max) - F(u_min)| and
    1e-4 of the force range from both, so that reachable or not does not hang on the last bits
    of the forward. Rows 0-3 (4 if the model reads a second field) are hard: a NaN demand, +Inf,
    -Inf, a NaN first field (the velocity), +Inf in the second. Deterministic (seed)."""
    from dampnet import _core

    rng = np.random.default_rng([seed, 55])
    fields = inverse_fields(model)
    lo_all, hi_all = np.asarray(model.sat_lo, float), np.asarray(model.sat_hi, float)
    feats = list(model.features)
    cols = []
    half = n // 2
    for name in fields:
        i = next(k for k, f in enumerate(feats) if _core.FEATURE_INPUTS[f] == name)
        lo, hi = lo_all[i], hi_all[i]
        span = hi - lo
        cols.append(np.concatenate([rng.uniform(lo, hi, half),
                                    rng.uniform(lo - 0.5 * span, hi + 0.5 * span, n - half)]))
    d = host_damper(model)
    try:
        u_min, u_max = d.control_range()
    except ValueError:  # no control input: every inverse is DN_E_MISMATCH; u anything
        u_min, u_max = 0.0, 1.0
    cols.append(rng.uniform(u_min, u_max, n))
    values = np.column_stack(cols).astype(np.float32) if cols else np.zeros((n, 0), np.float32)
    kw = damper_inputs(fields, values)
    kw.pop("u")
    f_lo = d.forces(u=np.full(n, u_min), **kw)[0]
    f_hi = d.forces(u=np.full(n, u_max), **kw)[0]
    region = rng.choice(3, size=n, p=[0.2, 0.6, 0.2])
    t = np.where(region == 0, rng.uniform(-0.5, -0.02, n),
                 np.where(region == 1, rng.uniform(0.02, 0.98, n), rng.uniform(1.02, 1.5, n)))
    delta = f_hi - f_lo
    demand = f_lo + t * delta
    force_range = 2.0 / float(model.out_gain) if getattr(model, "out_gain", None) else 1.0
    margin = np.maximum(0.02 * np.abs(delta), 1e-4 * force_range)
    near = np.minimum(np.abs(demand - f_lo), np.abs(demand - f_hi)) < margin
    top, bottom = np.maximum(f_lo, f_hi), np.minimum(f_lo, f_hi)
    # too near a limit's force (a narrow range): beyond it instead
    demand = np.where(near, np.where(demand > (top + bottom) / 2, top + 2 * margin, bottom - 2 * margin), demand)
    rows = np.column_stack([values, demand]).astype(np.float32)
    for k, (col, v) in enumerate([(-1, np.nan), (-1, np.inf), (-1, -np.inf), (0, np.nan), (1, np.inf)]):
        if k < n and col < len(fields):  # a column the model reads (the demand: -1)
            rows[k, col] = v
    return rows, fields


def write_vectors(path, vectors: Vectors, controller) -> Vectors:
    """The firmware's header (DN_FW_VECTORS): the inputs as float bits (NaN and infinities
    exactly), the road as doubles that round-trip (dn_real: rounded to float by the compiler in
    a DN_LOOP_FLOAT build), and the loop's configuration: LOOP_CONFIG, and `controller` (a
    dampnet.sim.vehicle.Controller: dampnet.recipes.control_laws.firmware_controller's for the model)
    as DN_FW_CONTROLLER (its kind) and DN_FW_CONTROLLER_SET(c), which sets every other field of a
    dn_controller c. With inverse cases (vectors.inv): DN_FW_N_INV, dn_fw_inv[DN_FW_N_INV][k] (float
    bits), DN_FW_INV_SET(in, row) and the demand's column DN_FW_INV_DEMAND (the firmware's inverse part)."""
    from dampnet import _core

    n, k = vectors.x.shape
    bits = vectors.x.view(np.uint32)
    fields = {name: value for name, value in controller.core_dict().items() if name != "kind"}
    ctrl = _core.CONTROLLER_KINDS[controller.kind][0]
    lines = ["/* Generated by dampnet.export.mcu.write_vectors: the firmware's inputs and road. */",
             "#ifndef DN_FW_VECTORS_H_", "#define DN_FW_VECTORS_H_", "#include <stdint.h>",
             '#include "dampnet/dampnet.h"',
             f"#define DN_FW_N_X {n}", f"#define DN_FW_N_STEPS {len(vectors.road)}",
             f"#define DN_FW_PRINT_EVERY {PRINT_EVERY}",
             f"#define DN_FW_DAMPER_EVAL {_core.DAMPER_EVALS[LOOP_CONFIG['damper_eval']][0]}",
             f"#define DN_FW_ACCEL_FEATURE {_core.ACCEL_FEATURES[LOOP_CONFIG['accel_feature']][0]}",
             f"#define DN_FW_CONTROLLER {ctrl}  /* {controller.kind} */",
             "#define DN_FW_CONTROLLER_SET(c) do { "
             + " ".join(f"(c).{name} = {float(value)!r};" for name, value in fields.items()) + " } while (0)",
             f"static const union {{ uint32_t u[{n}][{k}]; float f[{n}][{k}]; }} dn_fw_x_ = {{{{"]
    lines += ["  {" + ", ".join(f"0x{b:08x}u" for b in row) + "}," for row in bits]
    lines += ["}};", "#define dn_fw_x (dn_fw_x_.f)",
              f"static const dn_real dn_fw_road[{len(vectors.road)}][2] = {{"]
    lines += [f"  {{{z!r}, {v!r}}}," for z, v in vectors.road.tolist()]
    lines += ["};"]
    if vectors.inv is not None and len(vectors.inv):
        # the inverse's cases: the fields as float bits (NaN and infinities exactly), set into a
        # zeroed dn_damper_input by DN_FW_INV_SET(in, row) (u too: the forward it is timed against)
        ni, ki = vectors.inv.shape
        names = (*vectors.inv_fields, "u")
        assert ki == len(names) + 1, (ki, names)
        lines += [f"#define DN_FW_N_INV {ni}", f"#define DN_FW_INV_DEMAND {ki - 1}  /* the demanded force [N] */",
                  "#define DN_FW_INV_SET(in, r) do { "
                  + " ".join(f"(in).{name} = (dn_real)(r)[{j}];" for j, name in enumerate(names)) + " } while (0)",
                  f"static const union {{ uint32_t u[{ni}][{ki}]; float f[{ni}][{ki}]; }} dn_fw_inv_ = {{{{"]
        inv_bits = vectors.inv.astype(np.float32).view(np.uint32)
        lines += ["  {" + ", ".join(f"0x{b:08x}u" for b in row) + "}," for row in inv_bits]
        lines += ["}};", "#define dn_fw_inv (dn_fw_inv_.f)"]
    lines += ["#endif", ""]
    Path(path).write_text("\n".join(lines))
    return vectors


# ---- dampnet export MODEL --target cortex-m4|cortex-m7 --out DIR ----

def capacities_for(model) -> dict:
    """The smallest capacities (dampnet.h DN_CAP_*) that hold this model."""
    return {"INPUTS": len(model.features), "HIDDEN": int(np.asarray(model.w1).shape[0]),
            "HIDDEN2": int(np.asarray(model.w2).shape[0]) if model.w2 is not None else 0,
            "TERMS": len(model.terms), "TABLE_V": 2, "TABLE_U": 1,
            # no first-iterate grid for the cold inverse (4.5 KB of float per damper): a
            # controller calls dn_damper_inverse_near from its last command (dn_config.h)
            "INVERSE_V": 0, "INVERSE_U": 0}


#: the library's sources in an exported folder (and its private header, src/internal.hpp)
FOLDER_SOURCES = ("c_api_common.cpp", "c_api_mlp.cpp", "c_api_loop.cpp", "c_api_envelope.cpp")
#: the flags the folder compiles the library with besides the core's, as every measured build
#: (the root CMakeLists.txt's freestanding options): sections for --gc-sections, no fused
#: multiply-add (the host's rounding: the firmware's forces are the host kernel's bits), short
#: loops as stores (not calls to newlib-nano's byte-wise memset), no C++ runtime
FOLDER_FLAGS = ("-ffunction-sections", "-fdata-sections", "-ffp-contract=off", "-fno-tree-loop-distribute-patterns",
                "-fno-exceptions", "-fno-rtti", "-fno-threadsafe-statics")
#: the marker file of an exported folder (outputs.is_kind "export-target": what --force may replace)
FOLDER_MARKER = "dampnet-export.json"
FOLDER_SCHEMA = "dampnet.export-target/1"

_FOLDER_CMAKE = """# A ready-to-build dampnet for {cpu}, written by `dampnet export --target {cpu}`.
# The library (static, no exceptions, RTTI or heap; capacities fitted to model.h's network) and an
# example firmware for QEMU's {machine} (see README.md):
#   cmake -B build --toolchain cmake/arm-none-eabi.cmake && cmake --build build
# In your own firmware's CMake project: add_subdirectory(this folder) and link `dampnet`
# (set DN_EXAMPLE_FIRMWARE OFF), or compile the {n_sources} src/*.cpp with the flags below.
cmake_minimum_required(VERSION 3.18)
project(dampnet_{ident} LANGUAGES C CXX)
set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
set(DAMPNET_ARM_CPU {cpu} CACHE STRING "the core")
set(DN_CAPS {caps})
add_library(dampnet STATIC {sources})
target_include_directories(dampnet PUBLIC include ${{CMAKE_CURRENT_SOURCE_DIR}})
target_compile_definitions(dampnet PUBLIC DN_STATIC ${{DN_CAPS}})
target_compile_options(dampnet PRIVATE {flags})
# Release (-O3, as measured) when no build type is given: for this folder built on its own a
# normal variable (nothing written into the cache); inside another project (add_subdirectory)
# that project's build type applies, and without one the library alone gets -O3.
if(NOT CMAKE_BUILD_TYPE AND NOT CMAKE_CONFIGURATION_TYPES)
  if(CMAKE_SOURCE_DIR STREQUAL CMAKE_CURRENT_SOURCE_DIR)
    set(CMAKE_BUILD_TYPE Release)
  else()
    target_compile_options(dampnet PRIVATE -O3)
  endif()
endif()

option(DN_EXAMPLE_FIRMWARE "the example firmware (QEMU {machine})" ON)
if(DN_EXAMPLE_FIRMWARE)
  # dn_sizes.h: the objects' sizes in this build, read from the target's object code
  set(defs "")
  foreach(d ${{DN_CAPS}})
    list(APPEND defs "-D${{d}}")
  endforeach()
  try_compile(ok ${{CMAKE_CURRENT_BINARY_DIR}}/sizes-check SOURCES ${{CMAKE_CURRENT_SOURCE_DIR}}/example/sizes.cpp
    CMAKE_FLAGS "-DINCLUDE_DIRECTORIES=${{CMAKE_CURRENT_SOURCE_DIR}}/include"
    COMPILE_DEFINITIONS ${{defs}} -DDN_STATIC CXX_STANDARD 17 OUTPUT_VARIABLE log
    COPY_FILE ${{CMAKE_CURRENT_BINARY_DIR}}/dn_sizes_info.a)
  if(NOT ok)
    message(FATAL_ERROR "could not compile example/sizes.cpp for the target:\\n${{log}}")
  endif()
  file(STRINGS ${{CMAKE_CURRENT_BINARY_DIR}}/dn_sizes_info.a info REGEX "DNSIZES\\\\[[0-9,]+\\\\]")
  string(REGEX MATCH "DNSIZES\\\\[([0-9]+),([0-9]+),([0-9]+),([0-9]+),([0-9]+)\\\\]" _ "${{info}}")
  math(EXPR DN_SIZE_MLP "${{CMAKE_MATCH_1}}")
  math(EXPR DN_SIZE_DAMPER "${{CMAKE_MATCH_2}}")
  math(EXPR DN_SIZE_LOOP_MODEL "${{CMAKE_MATCH_3}}")
  math(EXPR DN_SIZE_LOOP_DATA "${{CMAKE_MATCH_4}}")
  math(EXPR DN_SIZE_ALIGN "${{CMAKE_MATCH_5}}")
  set(DN_CAP_DEFINES "${{DN_CAPS}}")
  configure_file(example/dn_sizes.h.in ${{CMAKE_CURRENT_BINARY_DIR}}/dn_sizes.h @ONLY)
  set(CMAKE_CXX_IMPLICIT_LINK_LIBRARIES "")
  set(CMAKE_CXX_IMPLICIT_LINK_DIRECTORIES "")
  add_executable(firmware example/firmware.c example/startup.c)
  set_target_properties(firmware PROPERTIES SUFFIX .elf LINKER_LANGUAGE C C_STANDARD 99)
  target_compile_options(firmware PRIVATE -ffunction-sections -fdata-sections -ffp-contract=off)
  target_compile_definitions(firmware PRIVATE DN_FW_PART=2 "DN_FW_CPU=\\"{cpu}\\""
    "DN_FW_VECTORS=\\"dn_fw_vectors.h\\"" "DN_FW_MODEL_HEADER=\\"model.h\\"" DN_FW_DESC_INIT=DN_MODEL_DESC_INIT
    DN_FW_FEATURE_NAMES=dn_model_feature_names DN_FW_N_INPUTS=DN_MODEL_N_INPUTS{params})
  target_include_directories(firmware PRIVATE ${{CMAKE_CURRENT_BINARY_DIR}} example)
  target_link_libraries(firmware PRIVATE dampnet m)
  target_link_options(firmware PRIVATE -T${{CMAKE_CURRENT_SOURCE_DIR}}/example/mps2.ld)
endif()
"""

_FOLDER_README = """# dampnet for {cpu}

Written by `dampnet export {model_name} --target {cpu}` (dampnet {version}). Model id `{model_id}`
(`DN_MODEL_ID` in `model.h`): {network}, inputs {inputs}.

| path | what |
| --- | --- |
| `model.h` | the model (weights, scalings, saturation limits, feature names): `DN_MODEL_DESC_INIT` (double), `DN_MODEL_FOLDED_INIT` (float weights with the scalings folded in) |
| `include/dampnet/` | the C ABI (`dampnet.h`: the functions; it includes `dn_config.h`, the build options this folder's CMakeLists.txt sets, `dn_types.h` and `dn_xmacro.h`) and the header-only C++ runtime it is built from |
| `src/` | the library's {n_sources} sources ({source_list}) and its private header `internal.hpp` |
| `CMakeLists.txt` | the static library `dampnet` with this model's capacities: {caps} |
| `cmake/arm-none-eabi.cmake` | the toolchain file (`DAMPNET_ARM_CPU` = cortex-m4 or cortex-m7) |
| `example/` | a firmware for QEMU's `{machine}` (start-up code, linker script `mps2.ld`, `firmware.c`) |
| `{marker}` | what wrote this folder (`dampnet export --force` replaces only a folder holding it) |

## Build and try it

```sh
cmake -B build --toolchain cmake/arm-none-eabi.cmake    # arm-none-eabi-gcc + newlib (Debian packages)
cmake --build build
qemu-system-arm -M {machine} -nographic -monitor none -serial none \\
  -semihosting-config enable=on,target=native -kernel build/firmware.elf
```

The firmware evaluates the model on {n_x} stored inputs and runs the quarter car over {seconds:g} s of
road, printing forces and states as the bits of their floats (and of the loop's reals: float on
the M4F, double on the M7).

## Into your firmware

1. Compile `src/*.cpp` as C++17 with your core's flags ({flags}) and {folder_flags} (what
   `CMakeLists.txt` uses and every figure below was measured with: `-ffp-contract=off` keeps the
   host's rounding, no fused multiply-add; `-fno-tree-loop-distribute-patterns` keeps short
   loops as stores instead of calls to newlib-nano's byte-wise `memset`), optimised (`-O3`
   measured), the definitions `DN_STATIC {caps}` (also for any C++ file of yours that includes
   the C++ headers), and link with `-Wl,--gc-sections` (newlib's libm and libgcc; no libstdc++,
   no heap). With CMake: `add_subdirectory` this folder and link `dampnet` (it sets no cache
   variable of yours; without a build type the library gets `-O3`).
2. Set the MLP up with `dn_mlp_init_folded` from `model.h`'s `DN_MODEL_FOLDED_INIT` (a
   `dn_mlp_folded_f`: the float weights with the input and output scalings already folded in, what
   `dn_mlp_init` would compute from `DN_MODEL_DESC_INIT` bit for bit): set-up then checks and copies
   floats only, so no software double routine and no double weights take flash (the example does
   this). With `DN_KERNEL_SMALL=1` (set here) the forward is compiled for exactly this model's
   input count.
3. Keep every object in static storage, and build the loop in one call:
   `dn_loop_model_init_neural(&veh, &ctrl, &folded, dn_model_feature_names, DN_MODEL_N_INPUTS, ...,
   mem, bytes, &model)` puts the damper and its network straight into the loop model's memory
   (the network held once; the example does this), then `dn_loop_data_init`. Memory of
   `dn_*_size()` bytes aligned to `dn_storage_align()` (`example/sizes.cpp` turns the sizes into
   compile-time constants for static arrays). `dn_mlp_init_folded` + `dn_damper_init_neural` +
   `dn_loop_model_init` give the same model (a loop model copies its damper, a damper its MLP).
4. The real-time call is `dn_loop_step` (or `dn_mlp_forward_f` / `dn_damper_force` alone): no
   allocation, no exceptions, bounded time, finite output for any input. This build links only
   the neural damper kind, the control laws without the damper's inverse (and the example's law),
   the linear and explicit acceleration feature and one damper evaluation
   per step (`DN_DAMPER_KINDS`, `DN_CONTROLLER_KINDS`, `DN_ACCEL_FEATURES`, `DN_DAMPER_EVALS`: anything else is refused
   at set-up with `DN_E_PARAM`); {loop_real}
5. Linker script: `.text`/`.rodata` in flash, `.data` copied and `.bss` zeroed by the start-up code,
   a stack of at least the peak measured for your core (dampnet's bench/RESULTS.md, "On a
   microcontroller"; the example paints and prints it); see the marked lines of `example/mps2.ld`.

{figures}
"""

#: the measured figures the folder's README quotes (bench/LOG.md, "On a microcontroller")
_FOLDER_FIGURES = """Figures for the 3-30-1 default model with these options (dampnet's bench/LOG.md): on a
Cortex-M4F (float loop) the float forward 1,447 instructions, the kernel 2,508 B of flash with its
weights, the quarter-car step 2,211 instructions on average and 2,363 at worst over two rough roads
(about 3,312 and 3,540 cycles by the TRM's timings, an estimate: 4.75x a 10 kHz step's budget at
168 MHz), kernel + loop + controller 15.2 KB of flash and 2.0 KB of RAM; on a Cortex-M7 (double
loop) 1,440 instructions, 3,292 B, 2,238 (worst 2,391) instructions, 18.8 KB and 2.6 KB."""


def _folder_sources() -> tuple[Path, Path, Path]:
    """(cpp root holding include/ and src/, the toolchain file's folder, the firmware's folder):
    the source tree's, or those CMakeLists.txt installs into the package (include/, src/,
    cmake/, embedded/)."""
    if source_tree():
        return ROOT / "cpp", ROOT / "cmake", ROOT / "cpp" / "embedded"
    pkg = Path(__file__).resolve().parents[1]  # the package root (dampnet/), where CMake installs them
    return pkg, pkg / "cmake", pkg / "embedded"


def export_target(model, target: str, out_dir, controller, overwrite: bool = False, model_name: str = "MODEL",
                  inputs=(), vectors: Vectors | None = None) -> Path:
    """The ready-to-build folder of `dampnet export MODEL --target CPU --out DIR`: model.h, the
    library's headers and sources, a CMakeLists.txt with the model's capacities, the toolchain
    file, an example firmware (its stored inputs and road: `vectors`, default 16 inputs and 1 s, no
    inverse cases), a README and the marker FOLDER_MARKER. `controller`: the example firmware's
    loop's (write_vectors).

    An existing DIR is replaced only with overwrite and only if it is such a folder (its marker),
    never if it is or holds one of `inputs` (the model's path); the folder is built in a staging
    directory and swapped in (outputs.staged_dir), so a kill leaves the old folder or the new."""
    import dampnet
    from dampnet.export.header import build_defines, header_text
    from dampnet.outputs import check_output_dir, json_text, staged_dir

    if target not in CPUS:
        raise ValueError(f"--target {target!r}: expected one of {', '.join(CPUS)}")
    out = check_output_dir(out_dir, "export-target", inputs, force=overwrite)
    if vectors is None:
        vectors = make_vectors(model, n_x=16, seconds=1.0, n_inv=0)  # the example: no inverse part
    src_root, cmake_dir, fw_dir = _folder_sources()
    caps = capacities_for(model)
    # a wider layer first raises the limit; the example's law is linked whatever it is
    cap_defs = build_defines(model) + target_defines(target, caps, controllers=controller_kinds(controller.kind))
    header = header_text(model, "dn_model")
    # the float weights with the scalings folded in (set-up without double arithmetic), when the
    # header has them (a model whose folded values overflow float has only DN_MODEL_DESC_INIT)
    params = " DN_FW_FOLDED_INIT=DN_MODEL_FOLDED_INIT" if "DN_MODEL_FOLDED_INIT" in header else ""
    if model.feature_params:
        params += (" DN_FW_PARAM_NAMES=dn_model_feature_param_names DN_FW_PARAM_VALUES=dn_model_feature_param_values"
                   " DN_FW_N_PARAMS=DN_MODEL_N_FEATURE_PARAMS")
    h2 = caps["HIDDEN2"]
    with staged_dir(out) as tmp:
        (tmp / "model.h").write_text(header)
        shutil.copytree(src_root / "include" / "dampnet", tmp / "include" / "dampnet")
        (tmp / "src").mkdir()
        for f in (*FOLDER_SOURCES, "internal.hpp"):
            shutil.copy2(src_root / "src" / f, tmp / "src" / f)
        (tmp / "cmake").mkdir()
        shutil.copy2(cmake_dir / "arm-none-eabi.cmake", tmp / "cmake" / "arm-none-eabi.cmake")
        (tmp / "example").mkdir()
        for f in ("firmware.c", "startup.c", "mps2.ld", "dn_sizes.h.in", "sizes.cpp"):
            shutil.copy2(fw_dir / f, tmp / "example" / f)
        write_vectors(tmp / "example" / "dn_fw_vectors.h", vectors, controller)
        (tmp / "CMakeLists.txt").write_text(_FOLDER_CMAKE.format(
            cpu=target, machine=CPUS[target]["machine"], ident=target.replace("-", "_"), caps=" ".join(cap_defs),
            params=params, n_sources=len(FOLDER_SOURCES), sources=" ".join(f"src/{f}" for f in FOLDER_SOURCES),
            flags=" ".join(FOLDER_FLAGS)))
        (tmp / "README.md").write_text(_FOLDER_README.format(
            cpu=target, machine=CPUS[target]["machine"], model_name=model_name, version=dampnet.__version__,
            model_id=model.model_id(), inputs=", ".join(model.features), n_x=len(vectors.x),
            seconds=len(vectors.road) * DT, marker=FOLDER_MARKER,
            network=f"{caps['INPUTS']}-{caps['HIDDEN']}-" + (f"{h2}-" if h2 else "") + f"1 {model.activation}",
            n_sources=len(FOLDER_SOURCES), source_list=", ".join(f"`{f}`" for f in FOLDER_SOURCES),
            caps=" ".join(cap_defs), flags=CPUS[target]["flags"],
            folder_flags=" ".join(f"`{f}`" for f in FOLDER_FLAGS), figures=_FOLDER_FIGURES,
            loop_real=("the loop's state and arithmetic are float (`DN_LOOP_FLOAT=1`: this core's FPU has no "
                       "double), within 1.2e-6 of the host's double loop's peaks over 10 s of the thesis rough road."
                       if LOOP_FLOAT[target] else
                       "the loop's state and arithmetic are double (`DN_LOOP_FLOAT=0`: this core's FPU has double), "
                       "as on the host.")))
        (tmp / FOLDER_MARKER).write_text(json_text({"schema": FOLDER_SCHEMA, "target": target,
                                                    "model_id": model.model_id(), "dampnet": dampnet.__version__}))
    return out
