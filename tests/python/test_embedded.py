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
  (measured, `pytest -s -k quarter_car` prints it: M4F float state 1.2e-6, M7 6.6e-7, where
  only the MLP's float rounding differs from the host's AVX2 kernel); the time t (a float sum
  of dt on the M4F: 4.1e-4 s off after 10,000 steps of 1 ms) within 1e-4 of 10 s.
* The damper's inverse (dn_damper_inverse on a float neural damper, issue 55) on 300 stored
  cases (motion inside and beyond the envelope, demands between and beyond the forces at the
  control limits, NaN and infinite demands and inputs): the host binding's control, force and
  status (test_inverse_equals_host_float_inverse).
* No C++ runtime and no heap are linked, dn_sizes.h matches the library, neither the float
  forward nor the loop step calls a software double routine, and only the neural damper kind
  is linked (DN_DAMPER_KINDS): no tanh or pow of the other kinds and terms.
* The MLP part alone (dn_firmware_kernel: dn_mlp_init_folded on the header's folded float
  weights, the forward; what bench/embedded.py's kernel flash counts) gives the host's forces and
  links no software double routine at all; the exporter's folded floats (P_FOLDED_INIT) are the C
  library's own folding of the double description, bit for bit (a host program compares); the
  integer float-to-double widening that set-up uses on the M4F is exact on the target.
Builds are cached in build/embedded-test/ (CMake rebuilds only what changed)."""

from __future__ import annotations

import json
import re
import subprocess

import numpy as np
import pytest

import needs

from cbuild import BUILD, ROOT, compile_program, run
import firmware_lab as emb  # bench/firmware_lab.py (the conftest puts bench/ on the path)
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
        pytest.fail(why, pytrace=False)
    # the dampnet package imported is this checkout's (its export folders use emb.mcu.ROOT's sources)
    assert emb.mcu.ROOT == ROOT, f"dampnet imported from {emb.mcu.ROOT}, the tests are {ROOT}'s"
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
    bdir = emb.build(cpu, TEST_DIR / cpu, vectors=vectors[0], caps={**emb.DEFAULT_CAPS, **emb.INVERSE_GRID_CAPS},
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
    assert len(out.states) == len(road) // emb.PRINT_EVERY
    cmp = emb.loop_vs_host(model, road, out)
    print(f"{cpu}: firmware vs host loop, error / peak:",
          {n: float(f"{r:.2e}") for n, r in cmp["error_over_peak"].items()}, f"time {out.final[0] - 10.0:+.2e} s")
    assert cmp["within"], cmp
    # time: t += dt in the loop's precision (float on the M4F: rounding accumulates; the road is
    # the caller's input, so only the reported time drifts)
    assert out.final[0] == pytest.approx(10.0, rel=1e-4 if emb.LOOP_FLOAT[cpu] else 1e-12)
    assert cmp["evals"] == (len(road), len(road))
    # the road moved the car: the sprung mass travelled centimetres
    assert cmp["peak"]["z_s"] > 5e-3


#: the firmware's inverse against the host's, in u: a share of the control range (the issue's
#: tolerance against a brute-force search is 1e-4, emb.INVERSE_U_TOLERANCE), where dF/du is steep;
#: where it is flat the kernels' float rounding leaves u less determined: there the two controls'
#: difference times dF/du is within twice the float force's rounding (each side stops within its
#: own: INVERSE_FORCE_ROUNDING_N). Measured (2026-12-04): 3.1e-5 at most, at dF/du = 5.7 N/V,
#: 8.8e-4 N; 1.0e-5 at most where dF/du > 20 N/V (before the first-iterate grid: 8.0e-6)
INVERSE_U_TOLERANCE = 2e-5
#: the default model's float force's rounding (dn_types.h: a float epsilon of |b_out| + sum |w_out|)
INVERSE_FORCE_ROUNDING_N = 2.0e-3


def test_inverse_equals_host_float_inverse(firmware, vectors, model):
    """The inverse part (issue 55): the firmware's dn_damper_inverse on a float neural damper built
    from the MLP, on the 300 stored cases (emb.make_vectors' inverse_vectors: v and a inside and
    beyond the envelope, demands between and beyond the forces at the control limits, a NaN demand,
    +-Inf demands, a NaN velocity, an infinite acceleration), equals the host binding's float
    neural damper's inverse (dampnet._core.Damper.inverse, double arithmetic around the float MLP):
    the same statuses (reachable, DN_W_UNREACHABLE, DN_W_SATURATED, DN_E_NONFINITE_INPUT where the
    host errors), the control within INVERSE_U_TOLERANCE of the control range and the force within
    1e-5 of the force range (the forward's tolerance; measured 7.7e-7). The evaluations need not be
    the host's (float arithmetic may take another Newton path). Cost (measured): about 1 ms here
    (the host's 300 inverses), plus ~0.04 s of QEMU per core in the shared firmware fixture's run
    (the part's ~6.5M instructions: the timed loops and the printed calls; 0.14 s against 0.12 s
    for the M4F firmware) and the fixture's one-off recompile of firmware.c when the vectors change."""
    cpu, _, out = firmware
    v = vectors[1]
    assert v.inv is not None and len(v.inv) == 300 and v.inv_fields == ("v", "a")
    cmp = emb.inverse_vs_host(model, v, out)
    print(f"{cpu}: firmware vs host inverse:", {k: cmp[k] for k in ("u_error_over_range", "force_error_over_range",
                                                                    "evals_host", "evals_firmware")})
    assert cmp["n"] == 300 and cmp["statuses_equal"], cmp
    assert cmp["u_error_over_range"] <= emb.INVERSE_U_TOLERANCE, cmp
    host = emb.mcu.host_damper(model)
    u_host = emb.host_inverse(model, v)[0]
    lo, hi = host.control_range()
    ok = out.inv_status >= 0
    du = np.abs(out.inv_u.astype(float) - u_host)[ok]
    mo = {"x": 0.0, "v": v.inv[ok, 0], "a": v.inv[ok, 1], "u_lag": 0.0, "temperature": 20.0}
    h = 1e-3 * (hi - lo)
    up, dn = np.minimum(u_host[ok] + h, hi), np.maximum(u_host[ok] - h, lo)
    slope = np.abs(host.forces(u=up, **mo)[0] - host.forces(u=dn, **mo)[0]) / (up - dn)
    assert np.all((du <= INVERSE_U_TOLERANCE * (hi - lo)) | (du * slope <= 2 * INVERSE_FORCE_ROUNDING_N)), cmp
    assert cmp["force_error_over_range"] <= emb.INVERSE_FORCE_TOLERANCE, cmp
    st = out.inv_status
    # the cases exercised every branch: reachable (some clamped), unreachable both ways, errors
    unreachable = (st >= 0) & (st & 16 > 0)
    assert ((st >= 0) & ~unreachable).sum() > 100 and unreachable.sum() > 100
    assert (st & 1 > 0).sum() > 50 and (st == -10).sum() == 3  # DN_W_SATURATED; DN_E_NONFINITE_INPUT
    assert np.all(np.isfinite(out.inv_u)) and np.all(np.isfinite(out.inv_force))
    # (every evaluation counted, the limits' included: an unreachable demand needs both limits)
    assert np.all(out.inv_evals[st < 0] <= 2) and np.all(out.inv_evals[unreachable] >= 2)
    assert out.inv_evals.max() <= 4 + 2 + 44  # DN_INVERSE_WARM_EVALS + 2 + DN_INVERSE_MAX_ITERS
    # unreachable: a control limit; reachable: the demand, to the forward's tolerance
    lo, hi = emb.mcu.host_damper(model).control_range()
    assert np.all(np.isin(out.inv_u[unreachable], np.array([lo, hi], dtype=out.inv_u.dtype)))
    reach = (st >= 0) & ~unreachable
    assert np.max(np.abs(out.inv_force[reach] - v.inv[reach, -1])) <= 1e-5 * 2.0 / model.out_gain
    assert out.time["inverse"][2] == out.time["damper_force"][2] == 300


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


def _soft_double(syms) -> list[str]:
    """libgcc's software double routines (AEABI and GCC names) among the symbols."""
    return sorted(f for f in syms if re.match(r"__aeabi_(d|\w*2d$)", f) or re.match(r"__(?!math_)\w*df\w*$", f))


def test_kernel_part_folded_init_equals_host_float_forward(firmware, vectors, model):
    """The MLP part alone: set-up by dn_mlp_init_folded from the header's folded float weights
    (no dn_mlp_init, no double description linked), forces as the host float forward's."""
    cpu, bdir, _ = firmware
    elf = emb.firmware_path(bdir, "dn_firmware_kernel")
    syms = _symbols(elf)
    assert "dn_mlp_init_folded" in syms and "dn_mlp_init" not in syms
    assert not any(s.startswith("dn_model_default_w1") for s in syms)  # the double weights
    out = emb.parse_output(emb.run(elf, cpu, timeout=120))
    assert out.cpu == cpu and out.part == 1 and out.errors == 0
    x = vectors[1].x
    y, status = emb.host_forces(model, x)
    err = np.abs(out.forces.astype(float) - y)
    assert err.max() <= 1e-5 * 2.0 / model.out_gain, err.max()
    np.testing.assert_array_equal(out.status, status)


def test_kernel_part_gives_the_host_sse_kernels_bits(firmware, vectors, tmp_path):
    """Under -ffp-contract=off (the presets') the targets' scalar kernel (one pass per partial sum,
    the padding neurons skipped) gives the host's SSE kernel's float bits for every stored input,
    statuses and masks included: a host program (the header-only Mlp<float> on the default
    header's double description, -mno-avx2) against the MLP part."""
    cpu, bdir, _ = firmware
    out = emb.parse_output(emb.run(emb.firmware_path(bdir, "dn_firmware_kernel"), cpu, timeout=120))
    src = tmp_path / "sse_forces.cpp"
    src.write_text(f"""#include <cstdint>
#include <cstdio>
#include <cstring>
#include "dampnet/mlp.hpp"
#include "dn_model_default.h"
#include "{vectors[0]}"
static dampnet::Mlp<float> m;
int main() {{
  const dn_mlp_desc d = DN_MODEL_DEFAULT_DESC_INIT;
  if (m.load(&d) != DN_OK) return 1;
  for (int i = 0; i < DN_FW_N_X; ++i) {{
    float y;
    uint32_t mask = 0, bits;
    const int st = m.forward(dn_fw_x[i], &y, &mask);
    std::memcpy(&bits, &y, sizeof bits);
    std::printf("%08x %d %u\\n", (unsigned)bits, st, (unsigned)mask);
  }}
  return 0;
}}
""")
    exe = compile_program([src], tmp_path / "sse_forces", cxx=True, include_dirs=[ROOT / "cpp" / "include",
                          ROOT / "export"], extra=["-mno-avx2", "-mno-fma", "-ffp-contract=off"])
    rows = [line.split() for line in run([exe]).stdout.splitlines()]
    host = np.array([int(r[0], 16) for r in rows], dtype=np.uint32)
    assert len(host) == len(out.forces)
    np.testing.assert_array_equal(out.forces.view(np.uint32), host)
    np.testing.assert_array_equal(out.status, [int(r[1]) for r in rows])
    np.testing.assert_array_equal(out.mask, [int(r[2]) for r in rows])


def test_kernel_part_links_no_double_routine(firmware):
    """On the M4F's single-precision FPU every double operation is a libgcc routine: the MLP
    part (set-up and forward) links none."""
    cpu, bdir, _ = firmware
    assert not _soft_double(_symbols(emb.firmware_path(bdir, "dn_firmware_kernel")))
    if cpu == "cortex-m4":  # the check itself sees them where they are: the loop's set-up narrows
        # the C ABI's double feature parameters to float, and nothing more
        assert _soft_double(_symbols(emb.firmware_path(bdir, "dn_firmware"))) == ["__aeabi_d2f", "__truncdfsf2"]


def test_widening_without_double_arithmetic_is_exact_on_the_m4f(vectors, tmp_path):
    """dn_mlp_init_folded fills a DN_DOUBLE_KERNEL 0 build's double saturation ranges by
    widening floats in integer arithmetic on the M4F (detail::widen_exact; a cast would link
    __aeabi_f2d): on the target, every kind of float (zeros, subnormals, normals, infinities)
    widens to the double the host's cast gives."""
    import struct

    rng = np.random.default_rng(3)
    bits = [0x00000000, 0x80000000, 0x00000001, 0x807fffff, 0x00400000, 0x00800000, 0x7f7fffff,
            0x7f800000, 0xff800000, 0x3f800000, 0xc0600000] + [int(b) for b in rng.integers(0, 2**32, 300)]
    bits = [b for b in bits if not ((b >> 23) & 0xff == 0xff and b & 0x7fffff)]  # no NaNs
    rows = [f"{{0x{b:08x}u, 0x{struct.unpack('<Q', struct.pack('<d', struct.unpack('<f', struct.pack('<I', b))[0]))[0]:016x}ull}}"
            for b in bits]
    src = tmp_path / "widen.cpp"
    src.write_text('#include <cstdint>\n#include <cstring>\n#include "dampnet/mlp.hpp"\n'
                   'static const struct { uint32_t f; uint64_t d; } cases[] = {' + ",\n".join(rows) + "};\n"
                   'extern "C" int dn_fw_semihost(int op, const void* arg);\n'
                   'extern "C" int main() {\n  int bad = 0;\n'
                   '  for (const auto& c : cases) {\n    float f;\n    std::memcpy(&f, &c.f, 4);\n'
                   '    const double d = dampnet::detail::widen_exact(f);\n    uint64_t b;\n'
                   '    std::memcpy(&b, &d, 8);\n    bad += b != c.d;\n  }\n'
                   '  dn_fw_semihost(0x04, bad ? "widen bad\\n" : "widen ok\\n");\n  return bad;\n}\n')
    flags = emb.CPUS["cortex-m4"]["flags"].split() + ["-O2"]
    elf = tmp_path / "widen.elf"
    run(["arm-none-eabi-g++", *flags, "-std=c++17", "-fno-exceptions", "-fno-rtti", "-DDN_STATIC",
         "-DDN_DOUBLE_KERNEL=0", f"-I{ROOT / 'cpp' / 'include'}", "-c", src, "-o", tmp_path / "widen.o"])
    run(["arm-none-eabi-gcc", *flags, "-c", ROOT / "cpp" / "embedded" / "startup.c", "-o", tmp_path / "startup.o"])
    run(["arm-none-eabi-gcc", *flags, "--specs=nano.specs", "-nostartfiles", "-Wl,--gc-sections",
         f"-T{ROOT / 'cpp' / 'embedded' / 'mps2.ld'}", tmp_path / "widen.o", tmp_path / "startup.o", "-o", elf])
    assert not _soft_double(_symbols(elf))
    assert "widen ok" in emb.run(elf, "cortex-m4", icount=False, timeout=60)


def test_exported_folded_floats_are_the_librarys_folding(vectors, model, tmp_path):
    """P_FOLDED_INIT (python/dampnet/export/header.py folds in Python) holds what the C library's
    load() makes of P_DESC_INIT, bit for bit: a host program loads both into Mlp<float> and
    compares every parameter, for the default model and random ones (tanh and sigmoid, one and
    two hidden layers, offsets folded into layer 1 or not)."""
    from kernel_cases import SHAPES, random_model

    from dampnet.export import write_header

    models = {"m_default": model}
    models.update({f"m_{k}": random_model(n, h, act, seed=k) for k, (n, h, act) in enumerate(SHAPES)})
    far = random_model(3, (30,), "tanh", seed=99)
    far.in_offset = far.in_offset + 100.0  # an offset beyond its input's range: not folded
    models["m_far"] = far
    lines = ["#include <cstdio>", "#include <cstring>", '#include "dampnet/mlp.hpp"']
    for name, m in models.items():
        write_header(m, tmp_path / f"{name}.h", name)
        lines.append(f'#include "{name}.h"')
    lines += ["""
using P = dampnet::MlpParams<float, DN_CAP_INPUTS, DN_CAP_HIDDEN, DN_CAP_HIDDEN2>;
template <class A> static bool eq(const A& a, const A& b) { return std::memcmp(&a, &b, sizeof a) == 0; }
static bool same(const P& a, const P& b) {
  static_assert(P::kTw == 0, "the host program is built without AVX2: no tw");
  return a.n_in == b.n_in && a.n_h1 == b.n_h1 && a.n_h2 == b.n_h2 && a.n_h1p == b.n_h1p &&
         a.n_h2p == b.n_h2p && a.in_offset_folded == b.in_offset_folded && eq(a.w1t, b.w1t) &&
         eq(a.b1, b.b1) && eq(a.w2t, b.w2t) && eq(a.b2, b.b2) && eq(a.w_out, b.w_out) &&
         eq(a.b_out, b.b_out) && eq(a.in_offset, b.in_offset) && eq(a.in_mid, b.in_mid) &&
         eq(a.sat_lo, b.sat_lo) && eq(a.sat_hi, b.sat_hi) && eq(a.out_offset, b.out_offset);
}
static dampnet::Mlp<float> a, b;
static int check(const char* name, const dn_mlp_desc& d, const dn_mlp_folded_f& f) {
  if (a.load(&d) != DN_OK || b.load_folded(&f) != DN_OK) return std::printf("%s: not loaded\\n", name), 1;
  if (!same(a.params(), b.params())) return std::printf("%s: differ\\n", name), 1;
  return std::printf("%s: same (offsets folded %d)\\n", name, int(b.params().in_offset_folded)), 0;
}
int main() {
  int bad = 0;"""]
    for name in models:
        P = name.upper()
        lines.append(f'  {{ const dn_mlp_desc d = {P}_DESC_INIT; const dn_mlp_folded_f f = {P}_FOLDED_INIT; '
                     f'bad += check("{name}", d, f); }}')
    lines += ["  return bad;", "}", ""]
    src = tmp_path / "folded_check.cpp"
    src.write_text("\n".join(lines))
    exe = compile_program([src], tmp_path / "folded_check", cxx=True,
                          include_dirs=[ROOT / "cpp" / "include", tmp_path], extra=["-mno-avx2", "-mno-fma"])
    text = run([exe]).stdout
    assert text.count(": same") == len(models), text
    assert "offsets folded 0" in text and "offsets folded 1" in text


def test_the_step_calls_no_software_double_and_links_only_the_neural_kind(firmware):
    """The quarter-car step on the M4F's float state and on the M7's hardware double calls no
    libgcc double routine; a build of the neural kind only (DN_DAMPER_KINDS) links none of the
    other kinds' libm functions (parametric: tanh; terms: pow); a build without the force-tracking
    laws (DN_CONTROLLER_KINDS) does not reach the damper's inverse from the step."""
    cpu, bdir, _ = firmware
    elf = emb.firmware_path(bdir)
    reach = _calls_from(elf, "dn_loop_step")
    assert any("step" in f for f in reach) and any("forward" in f for f in reach), reach  # the MLP kernel
    assert not _soft_double(reach), _soft_double(reach)
    # the force-tracking laws are left out (DN_CONTROLLER_KINDS, the firmware runs on-off
    # skyhook): the step does not reach the damper's inverse (its 3.6 KB stay out of the loop)
    assert not [f for f in reach if "inverse" in f], sorted(f for f in reach if "inverse" in f)
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
    cmake_text = (out / "CMakeLists.txt").read_text()
    assert "DN_CAP_INPUTS=3 DN_CAP_HIDDEN=30" in cmake_text
    assert "DN_FW_FOLDED_INIT=DN_MODEL_FOLDED_INIT" in cmake_text and "DN_KERNEL_SMALL=1" in cmake_text
    assert "dn_mlp_init_folded" in (out / "README.md").read_text()
    again = subprocess.run(cmd, capture_output=True, text=True)
    assert again.returncode == 2 and "refusing to overwrite" in again.stderr
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    subprocess.run(["cmake", "-S", out, "-B", out / "build", *gen, "--toolchain",
                    out / "cmake" / "arm-none-eabi.cmake"], check=True, capture_output=True)
    subprocess.run(["cmake", "--build", out / "build"], check=True, capture_output=True)
    fw = emb.parse_output(emb.run(out / "build" / "firmware.elf", "cortex-m4", icount=False))
    assert fw.errors == 0 and fw.final is not None and fw.evals == 1000
    assert "dn_mlp_init_folded" in _symbols(out / "build" / "firmware.elf")
    x = emb.make_vectors(model, n_x=16, seconds=1.0).x
    y, status = emb.host_forces(model, x)
    assert np.max(np.abs(fw.forces - y)) <= 1e-5 * 2.0 / model.out_gain
    np.testing.assert_array_equal(fw.status, status)


def test_export_target_folder_sizes_itself_for_a_wide_averaged_network(vectors, tmp_path):
    """Capacity from the model (issue 33): three 30-neuron restarts averaged into one 90-neuron
    network, wider than the library's default 64: the exported folder raises DN_MAX_HIDDEN to 90
    itself, builds, and its firmware gives the host's float forces."""
    import shutil

    import dampnet
    from dampnet.rig import generate

    wide = dampnet.train(generate("quick", seed=0), seed=0, restarts=3, average=3, workers=1, max_epochs=30).model
    assert wide.hidden == (90,)
    out = emb.export_target(wide, "cortex-m4", tmp_path / "m4")
    assert "DN_MAX_HIDDEN=90 DN_CAP_INPUTS=3 DN_CAP_HIDDEN=90" in (out / "CMakeLists.txt").read_text()
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    subprocess.run(["cmake", "-S", out, "-B", out / "build", *gen, "--toolchain",
                    out / "cmake" / "arm-none-eabi.cmake"], check=True, capture_output=True)
    subprocess.run(["cmake", "--build", out / "build"], check=True, capture_output=True)
    fw = emb.parse_output(emb.run(out / "build" / "firmware.elf", "cortex-m4", icount=False))
    assert fw.errors == 0 and fw.evals == 1000
    x = emb.make_vectors(wide, n_x=16, seconds=1.0).x
    y, status = emb.host_forces(wide, x)
    assert np.max(np.abs(fw.forces - y)) <= 1e-5 * 2.0 / wide.out_gain
    np.testing.assert_array_equal(fw.status, status)


# ---- the exported folder: what --force may replace, crash safety, its README (issue 29) ----

DEFAULT_JSON = ROOT / "export" / "dn_model_default.json"


def _export(*args) -> subprocess.CompletedProcess:
    import sys

    return subprocess.run([sys.executable, "-m", "dampnet.cli", "export", *map(str, args)],
                          capture_output=True, text=True, timeout=120)


def test_export_target_never_replaces_a_folder_holding_its_input(tmp_path):
    """--force replaced any folder holding model.h and CMakeLists.txt, deleting an input model in
    it: the input model's own folder (or one containing it) is refused, the model intact."""
    model_dir = tmp_path / "m"
    model_dir.mkdir()
    (model_dir / "model.json").write_bytes(DEFAULT_JSON.read_bytes())
    for f in ("model.h", "CMakeLists.txt"):  # what the old check looked for
        (model_dir / f).write_text("// mine\n")
    for model, out in ((model_dir, model_dir), (model_dir / "model.json", model_dir), (model_dir, tmp_path)):
        proc = _export(model, "--target", "cortex-m4", "--out", out, "--force")
        assert proc.returncode == 2 and "is an input of this command" in proc.stderr, proc.stderr
        assert len(proc.stderr.strip().splitlines()) == 1 and "Traceback" not in proc.stderr
    assert (model_dir / "model.json").read_bytes() == DEFAULT_JSON.read_bytes()
    assert (model_dir / "model.h").read_text() == "// mine\n"


def test_export_target_force_replaces_only_an_exported_folder(tmp_path):
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep")
    proc = _export(DEFAULT_JSON, "--target", "cortex-m4", "--out", other, "--force")
    assert proc.returncode == 2 and "not a dampnet export-target directory" in proc.stderr, proc.stderr
    assert sorted(p.name for p in other.iterdir()) == ["notes.txt"]
    out = tmp_path / "fw"
    assert _export(DEFAULT_JSON, "--target", "cortex-m4", "--out", out).returncode == 0
    marker = json.loads((out / emb.FOLDER_MARKER).read_text())
    assert marker["schema"] == emb.FOLDER_SCHEMA and marker["target"] == "cortex-m4"
    (out / "stale.txt").write_text("from the previous export")
    proc = _export(DEFAULT_JSON, "--target", "cortex-m7", "--out", out, "--force")
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / emb.FOLDER_MARKER).read_text())["target"] == "cortex-m7"
    assert not (out / "stale.txt").exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


KILL_EXPORT = """
import os, sys
from dampnet import outputs
from dampnet.cli import main
def checkpoint(step):
    if step == sys.argv[1]:
        os._exit(9)
outputs._checkpoint = checkpoint
main(["export", sys.argv[2], "--target", "cortex-m7", "--out", sys.argv[3], "--force"])
"""


@pytest.mark.parametrize("step, target", [("staged", "cortex-m4"), ("exchanged", "cortex-m7")])
def test_a_kill_while_exporting_leaves_the_old_folder_or_the_new(tmp_path, step, target):
    """The folder is written in a staging directory and swapped in: killed after writing all of
    it but before the swap, the old folder is untouched; after the swap, the new one is whole."""
    import sys

    from dampnet.outputs import clean_stale

    out = tmp_path / "fw"
    assert _export(DEFAULT_JSON, "--target", "cortex-m4", "--out", out).returncode == 0
    (out / "old.txt").write_text("the previous export")
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    proc = subprocess.run([sys.executable, "-c", KILL_EXPORT, step, str(DEFAULT_JSON), str(out)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 9, proc.stderr
    clean_stale(tmp_path)  # what the next run does first
    assert json.loads((out / emb.FOLDER_MARKER).read_text())["target"] == target
    now = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    if step == "staged":
        assert now == before
    else:
        assert not (out / "old.txt").exists() and len(now) == len(before) - 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fw"]


def _backticked_flags(text: str) -> set[str]:
    return set(re.findall(r"`(-f[\w=-]+)`", text))


def test_export_folder_readme_states_its_cmakelists_flags_model_id_and_sources(model, tmp_path):
    """The README's integration steps give the flags the folder's CMakeLists compiles the library
    with (-ffp-contract=off and -fno-tree-loop-distribute-patterns were missing), the model id of
    model.h (it said "Model id ``") and as many sources as src/ holds (it said three of four)."""
    out = emb.export_target(model, "cortex-m4", tmp_path / "fw")
    readme, cmake_text = (out / "README.md").read_text(), (out / "CMakeLists.txt").read_text()
    cmake_flags = set(re.search(r"target_compile_options\(dampnet PRIVATE ([^)]*)\)", cmake_text).group(1).split())
    step1 = re.search(r"\n1\. (.*?)\n2\. ", readme, re.S).group(1)
    assert {"-ffp-contract=off", "-fno-tree-loop-distribute-patterns"} <= cmake_flags
    assert _backticked_flags(step1) == cmake_flags
    model_id = re.search(r'#define DN_MODEL_ID "([0-9a-f]+)"', (out / "model.h").read_text()).group(1)
    assert f"Model id `{model_id}`" in readme and model_id == model.model_id()
    sources = sorted(p.name for p in (out / "src").glob("*.cpp"))
    stated = int(re.search(r"the library's (\d+) sources", readme).group(1))
    assert stated == len(sources) == 4
    assert sorted(re.findall(r"src/(\w+\.cpp)", cmake_text)) == sources
    assert "CMAKE_BUILD_TYPE Release CACHE" not in cmake_text


def test_export_folder_as_a_subdirectory_leaves_the_parents_build_type(model, tmp_path):
    """add_subdirectory(the folder) in a firmware's own CMake project: the library builds (-O3
    without a build type) and the parent's cache keeps its CMAKE_BUILD_TYPE (empty, or its own);
    the folder wrote Release into it."""
    import shutil

    why = emb.toolchain_missing()
    if why:
        pytest.fail(why, pytrace=False)
    folder = emb.export_target(model, "cortex-m4", tmp_path / "fw")
    parent = tmp_path / "parent"
    parent.mkdir()
    (parent / "CMakeLists.txt").write_text("cmake_minimum_required(VERSION 3.18)\nproject(parent LANGUAGES C CXX)\n"
                                           f"add_subdirectory({folder.as_posix()} dampnet)\n")
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    for build_type in ("", "Debug"):
        bdir = tmp_path / f"build{build_type}"
        run(["cmake", "-S", parent, "-B", bdir, *gen, f"--toolchain={folder / 'cmake' / 'arm-none-eabi.cmake'}",
             "-DDN_EXAMPLE_FIRMWARE=OFF", *([f"-DCMAKE_BUILD_TYPE={build_type}"] if build_type else [])])
        run(["cmake", "--build", bdir, "--target", "dampnet"])
        cache = (bdir / "CMakeCache.txt").read_text()
        assert re.search(r"^CMAKE_BUILD_TYPE:\w+=(.*)$", cache, re.M).group(1) == build_type
        assert (bdir / "dampnet" / "libdampnet.a").is_file()


def test_the_per_step_trace_counts_what_systick_counts(model, vectors):
    """bench/embedded.py's worst step comes from a QEMU execution trace that counts each step's
    instructions (per_call_instructions). On 300 steps of the rough road its mean is the
    firmware's SysTick mean (the timed loop minus the same loop calling an empty function: an
    independent count) plus the call's own few instructions: within 0 .. 1.5 % of a step (34
    instructions; measured +10, +17 since the step checks the physical bounds, +24.0 of 2,251
    since issue 30 moved more of the step into functions of its own; counting blocks past QEMU's
    1 KB page boundaries, as the trace did, gave +259)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_embedded", ROOT / "bench" / "embedded.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    header = TEST_DIR / "dn_fw_vectors_short.h"
    v = emb.make_vectors(model, n_x=20, seconds=0.3, n_inv=0)  # no inverse part: the steps only
    emb.write_vectors(header, v)
    bdir = emb.build("cortex-m4", TEST_DIR / "cortex-m4-short", vectors=header, targets=("dn_firmware",))
    elf = emb.firmware_path(bdir)
    systick = emb.parse_output(emb.run(elf, "cortex-m4")).instructions("step")
    steps = bench.per_call_instructions(elf, "cortex-m4", "dn_loop_step", TEST_DIR / "trace.log")
    assert len(steps) == len(v.road) == 300
    assert 0 <= steps.mean() - systick <= 0.015 * systick, (steps.mean(), systick)
    assert steps.max() > steps.mean() > steps.min() > 0.9 * systick
