"""The C library on a microcontroller (issue 19): the firmware of cpp/embedded/, cross-built
for Cortex-M4F and Cortex-M7 (cmake/arm-none-eabi.cmake, Debian's gcc-arm-none-eabi and
newlib) and run in QEMU (mps2-an386, mps2-an500; semihosting), against the host runtime.

* The MLP alone on 1,000 stored inputs, half of them out of the saturation range and
  six non-finite: the target's float forces equal the host runtime's float forward
  (dampnet._core, the host's SIMD kernel) to 1e-5 of the model's force range, with the same
  statuses. (Measured: 5e-7; the kernels' tanh approximations differ by up to 5e-7.)
* The quarter car (thesis Table 5, RK4 with one damper evaluation per step and the linearised
  acceleration feature, on-off skyhook through a 5 ms command filter, float MLP; the loop state
  in float on the M4F (DN_LOOP_FLOAT: its FPU has no double) and in double on the M7) over
  10 s of the thesis's rough road (10,000 steps), against the host loop (double state): the
  state every 100 steps and at the end within 1e-4 of each quantity's peak over the run
  (measured: M7 below 1e-6, only the MLP's float rounding differs; M4F float state at most
  6.3e-7 of the peak); the time t (a float sum of dt on the M4F: 4.1e-4 s off after 10,000
  steps of 1 ms) within 1e-4 of 10 s.
* No C++ runtime and no heap are linked, dn_sizes.h matches the library, neither the float
  forward nor the loop step calls a software double routine, and only the neural damper kind
  is linked (DN_DAMPER_KINDS): no tanh or pow of the other kinds and terms.
Builds are cached in build/embedded-test/ (CMake rebuilds only what changed)."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

from cbuild import BUILD, ROOT
from dampnet import embedded as emb
from dampnet.modeldir import load_model

CPUS = sorted(emb.CPUS)
TEST_DIR = BUILD / "embedded-test"


@pytest.fixture(scope="module")
def model():
    return load_model(ROOT / "export" / "dn_model_default.json")


@pytest.fixture(scope="module")
def vectors(model):
    why = emb.toolchain_missing()
    if why:
        pytest.skip(why)
    TEST_DIR.mkdir(parents=True, exist_ok=True)
    path = TEST_DIR / "dn_fw_vectors.h"
    v = emb.make_vectors(model)
    text_before = path.read_text() if path.is_file() else None
    emb.write_vectors(TEST_DIR / "dn_fw_vectors.new.h", v)
    new = (TEST_DIR / "dn_fw_vectors.new.h").read_text()
    if new != text_before:  # unchanged: the builds stay cached
        path.write_text(new)
    return path, v


@pytest.fixture(scope="module", params=CPUS)
def firmware(request, vectors):
    cpu = request.param
    checks = ("dn_float_kernel_check",) + (("dn_float_loop_check",) if emb.LOOP_FLOAT[cpu] else ())
    bdir = emb.build(cpu, TEST_DIR / cpu, vectors=vectors[0],
                     targets=("dn_firmware", "dn_firmware_kernel") + checks)
    out = emb.parse_output(emb.run(emb.firmware_path(bdir), cpu, timeout=120))
    return cpu, bdir, out


def test_firmware_runs_without_errors(firmware):
    cpu, _, out = firmware
    assert out.cpu == cpu and out.part == 2
    assert out.errors == 0
    assert out.sizes["mlp"] > 0 and out.sizes["loop_model"] >= out.sizes["mlp"]


def test_forces_equal_host_float_forward(firmware, vectors, model):
    _, _, out = firmware
    x = vectors[1].x
    assert out.forces is not None and len(out.forces) == len(x) == 1000
    y, status = emb.host_forces(model, x)
    force_range = 2.0 / model.out_gain  # the output's mapminmax range [N]
    assert np.all(np.isfinite(out.forces))
    err = np.abs(out.forces.astype(float) - y)
    assert err.max() <= 1e-5 * force_range, (err.max(), force_range)
    np.testing.assert_array_equal(out.status, status)
    # the inputs did exercise the clamping: out of range and non-finite ones
    assert (out.status == 1).sum() > 300 and ((out.status & 2) > 0).sum() == 3 and (out.status == 0).sum() > 400


def test_quarter_car_equals_host_loop(firmware, vectors, model):
    cpu, _, out = firmware
    road = vectors[1].road
    states, final, evals = emb.host_loop(model, road)
    assert [k for k, _, _ in out.states] == [k for k, _ in states]
    fw = np.array([s for _, s, _ in out.states])
    host = np.array([s for _, s in states])
    assert fw.shape == host.shape == (len(road) // emb.PRINT_EVERY, 13)
    names = ["z_s", "v_s", "z_us", "v_us", "u_cmd"]
    idx = [1, 2, 3, 4, 12]
    peak = np.abs(host[:, idx]).max(axis=0)
    assert np.all(peak > 0)
    err = np.abs(fw[:, idx] - host[:, idx]).max(axis=0)
    assert np.all(err <= 1e-4 * peak), dict(zip(names, err / peak))
    np.testing.assert_allclose(out.final[idx], final[idx], rtol=0, atol=1e-4 * peak.max())
    # time: t += dt in the loop's precision (float on the M4F: rounding accumulates; the road is
    # the caller's input, so only the reported time drifts)
    assert out.final[0] == pytest.approx(10.0, rel=1e-4 if emb.LOOP_FLOAT[cpu] else 1e-12)
    assert out.evals == evals == len(road)
    # the road moved the car: the sprung mass travelled centimetres
    assert peak[0] > 5e-3


def _symbols(elf) -> set[str]:
    nm = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True).stdout
    return {line.split()[-1] for line in nm.splitlines() if line.strip()}


def _calls_from(elf, root: str) -> set[str]:
    """Every function reachable from root through direct calls (bl/b.w to a symbol)."""
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)],
                         capture_output=True, text=True, check=True).stdout
    calls: dict[str, set[str]] = {}
    cur = None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <([^>]+)>:$", line)
        if m:
            cur = m.group(1)
            calls[cur] = set()
        elif cur:
            m = re.search(r"\s(?:bl|blx|b|b\.w|b\.n|beq\.w|bne\.w)\s+[0-9a-f]+ <([^>+]+)>", line)
            if m and m.group(1) != cur:
                calls[cur].add(m.group(1))
    seen, todo = set(), [root]
    while todo:
        f = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        todo.extend(calls.get(f, ()))
    return seen


def test_no_cxx_runtime_no_heap_and_a_float_forward_without_double(firmware):
    cpu, bdir, _ = firmware
    for name in ("dn_firmware", "dn_firmware_kernel"):
        syms = _symbols(emb.firmware_path(bdir, name))
        cxx = sorted(s for s in syms if s.startswith(("_Znw", "_Zdl", "__cxa_", "__gxx_", "_ZSt", "_ZNSt")))
        assert not cxx, cxx
        heap = sorted(s for s in syms if s in ("malloc", "free", "_sbrk", "_malloc_r", "_free_r"))
        assert not heap, heap
    reach = _calls_from(emb.firmware_path(bdir, "dn_firmware_kernel"), "dn_mlp_forward_f")
    assert any("forward" in f for f in reach), reach
    assert not _soft_double(reach), _soft_double(reach)
    # the float kernel compiled with -Wdouble-promotion -Werror (dn_float_kernel_check)
    assert list((bdir / "cpp" / "embedded").rglob("float_kernel_check.cpp.obj"))


def _soft_double(functions) -> list[str]:
    return sorted(f for f in functions if re.match(r"__aeabi_d|__aeabi_[fi]2d|__aeabi_d2|__.*df[23]", f))


def test_the_step_calls_no_software_double_and_links_only_the_neural_kind(firmware):
    """The quarter-car step on the M4F's float state and on the M7's hardware double calls no
    libgcc double routine; a build of the neural kind only (DN_DAMPER_KINDS) links none of the
    other kinds' libm functions (parametric: tanh; terms: pow)."""
    cpu, bdir, _ = firmware
    elf = emb.firmware_path(bdir)
    reach = _calls_from(elf, "dn_loop_step")
    assert any("step" in f for f in reach) and any("force_da" in f for f in reach), reach
    assert not _soft_double(reach), _soft_double(reach)
    other_kinds = {"tanh", "tanhf", "pow", "powf"} & _symbols(elf)
    assert not other_kinds, other_kinds
    if emb.LOOP_FLOAT[cpu]:  # the float loop compiled with -Wdouble-promotion -Werror
        assert list((bdir / "cpp" / "embedded").rglob("float_loop_check.cpp.obj"))


def test_export_target_folder_builds_and_runs(vectors, model, tmp_path):
    """`dampnet export MODEL --target cortex-m4 --out DIR`: the folder builds on its own with
    its toolchain file (library with the model's capacities, example firmware) and the firmware
    gives the host's forces; an existing folder is refused without --force."""
    import shutil
    import sys

    out = tmp_path / "m4"
    cmd = [sys.executable, "-m", "dampnet.cli", "export", str(ROOT / "export" / "dn_model_default.json"),
           "--target", "cortex-m4", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert (out / "model.h").is_file() and (out / "README.md").is_file()
    assert "DN_CAP_INPUTS=3 DN_CAP_HIDDEN=30" in (out / "CMakeLists.txt").read_text()
    again = subprocess.run(cmd, capture_output=True, text=True)
    assert again.returncode == 2 and "refusing to overwrite" in again.stderr
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    subprocess.run(["cmake", "-S", out, "-B", out / "build", *gen, "--toolchain",
                    out / "cmake" / "arm-none-eabi.cmake"], check=True, capture_output=True)
    subprocess.run(["cmake", "--build", out / "build"], check=True, capture_output=True)
    fw = emb.parse_output(emb.run(out / "build" / "firmware.elf", "cortex-m4", icount=False))
    assert fw.errors == 0 and fw.final is not None and fw.evals == 1000
    x = emb.make_vectors(model, n_x=16, seconds=1.0).x
    y, status = emb.host_forces(model, x)
    assert np.max(np.abs(fw.forces - y)) <= 1e-5 * 2.0 / model.out_gain
    np.testing.assert_array_equal(fw.status, status)
