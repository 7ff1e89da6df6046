"""The C++ MLP kernel equals a torch float64 reference on every path:
pybind11 (double and float), the C ABI through cffi, and the generated header
compiled into C++ (compile-time sizes) and C (run-time model from P_DESC_INIT)."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import needs

from cbuild import compile_program
from cdefs import MLP_CDEF
from dampnet import paths
from dampnet.export import write_header
from kernel_cases import (DOUBLE_TOL, FLOAT_TOL, SHAPES, random_inputs, random_model,
                          torch_reference)


@pytest.mark.parametrize("n_in,hidden,act", SHAPES)
def test_pybind_double_and_float_match_torch(n_in, hidden, act):
    model = random_model(n_in, hidden, act, seed=n_in * 100 + hidden[0])
    x = random_inputs(model, 2000, seed=1)
    ref = torch_reference(model, x)
    assert np.max(np.abs(model.predict(x) - ref)) <= DOUBLE_TOL
    assert np.max(np.abs(model.predict(x, single=True) - ref)) <= FLOAT_TOL


def test_random_shapes_sweep_matches_torch():
    """Many shapes drawn at random across the whole supported range."""
    rng = np.random.default_rng(42)
    for k in range(60):
        n_in = int(rng.integers(1, 9))
        hidden = (int(rng.integers(1, 65)),) + ((int(rng.integers(1, 65)),) if k % 2 else ())
        act = "tanh" if k % 3 else "sigmoid"
        model = random_model(n_in, hidden, act, seed=k)
        x = random_inputs(model, 200, seed=k)
        ref = torch_reference(model, x)
        assert np.max(np.abs(model.predict(x) - ref)) <= DOUBLE_TOL, (n_in, hidden, act)
        assert np.max(np.abs(model.predict(x, single=True) - ref)) <= FLOAT_TOL, (n_in, hidden, act)


CDEF = MLP_CDEF + """
int dn_version(void);
const char* dn_status_str(int status);
int dn_mlp_create(const dn_mlp_desc* desc, dn_mlp** out);
void dn_mlp_destroy(dn_mlp* m);
int dn_mlp_forward(const dn_mlp* m, const double* x, double* y, uint32_t* clamped_mask);
int dn_mlp_forward_f(const dn_mlp* m, const float* x, float* y, uint32_t* clamped_mask);
"""


@pytest.fixture(scope="module")
def cffi_lib():
    cffi = needs.need_module("cffi")
    ffi = cffi.FFI()
    ffi.cdef(CDEF)
    return ffi, ffi.dlopen(str(paths.shared_library()))


def _desc(ffi, model, keep):
    def arr(a):
        a = np.ascontiguousarray(a, dtype=np.float64)
        keep.append(a)
        return ffi.cast("const double*", a.ctypes.data)

    d = ffi.new("dn_mlp_desc*")
    d.n_inputs, d.n_hidden1 = model.n_inputs, model.hidden[0]
    d.n_hidden2 = model.hidden[1] if len(model.hidden) > 1 else 0
    d.activation = 0 if model.activation == "tanh" else 1
    d.w1, d.b1, d.w_out, d.b_out = arr(model.w1), arr(model.b1), arr(model.w_out), arr([model.b_out])
    if model.w2 is not None:
        d.w2, d.b2 = arr(model.w2), arr(model.b2)
    d.in_offset, d.in_gain = arr(model.in_offset), arr(model.in_gain)
    d.sat_lo, d.sat_hi = arr(model.sat_lo), arr(model.sat_hi)
    d.in_ymin, d.out_offset, d.out_gain, d.out_ymin = (model.in_ymin, model.out_offset,
                                                       model.out_gain, model.out_ymin)
    return d


@pytest.mark.parametrize("n_in,hidden,act", SHAPES[::2])
def test_c_abi_through_cffi_matches_torch_and_pybind(cffi_lib, n_in, hidden, act):
    ffi, lib = cffi_lib
    model = random_model(n_in, hidden, act, seed=7 + n_in)
    keep: list = []
    handle = ffi.new("dn_mlp**")
    assert lib.dn_mlp_create(_desc(ffi, model, keep), handle) == 0
    x = random_inputs(model, 300, seed=3)
    ref = torch_reference(model, x)
    y = ffi.new("double*")
    yf = ffi.new("float*")
    got, got_f = np.empty(len(x)), np.empty(len(x))
    for i, row in enumerate(x):
        assert lib.dn_mlp_forward(handle[0], ffi.new("double[]", list(row)), y, ffi.NULL) >= 0
        assert lib.dn_mlp_forward_f(handle[0], ffi.new("float[]", list(row)), yf, ffi.NULL) >= 0
        got[i], got_f[i] = y[0], yf[0]
    lib.dn_mlp_destroy(handle[0])
    assert np.max(np.abs(got - ref)) <= DOUBLE_TOL
    assert np.max(np.abs(got_f - ref)) <= FLOAT_TOL
    assert np.array_equal(got, model.predict(x))  # same kernel behind both front doors


def test_c_abi_refuses_bad_models_with_named_status(cffi_lib):
    ffi, lib = cffi_lib
    model = random_model(3, (4,), "tanh", seed=1)
    keep: list = []
    d = _desc(ffi, model, keep)
    d.n_inputs = 9
    handle = ffi.new("dn_mlp**")
    st = lib.dn_mlp_create(d, handle)
    assert st < 0 and handle[0] == ffi.NULL
    assert b"DN_E_SIZE" in ffi.string(lib.dn_status_str(st))


def _write_header_program(models, tmp_path, cxx: bool):
    """One program including every model's header; it prints outputs for inputs on stdin."""
    lines = ["#include <stdio.h>", '#include "dampnet/dampnet.h"']
    if cxx:
        lines.append('#include "dampnet/mlp.hpp"')
    for k, m in enumerate(models):
        write_header(m, tmp_path / f"m{k}.h", prefix=f"m{k}")
        lines.append(f'#include "m{k}.h"')
    body = ["int main(void) {", "  int k, n, i; double x[8];",
            "  while (scanf(\"%d %d\", &k, &n) == 2) {",
            "    for (i = 0; i < n; ++i) if (scanf(\"%lf\", &x[i]) != 1) return 2;"]
    for k, m in enumerate(models):
        P = f"M{k}"
        if cxx:
            body += [f"    if (k == {k}) {{",
                     f"      static dampnet::StaticMlp<double, {P}_N_INPUTS, {P}_N_HIDDEN1, {P}_N_HIDDEN2> md;",
                     f"      static dampnet::StaticMlp<float, {P}_N_INPUTS, {P}_N_HIDDEN1, {P}_N_HIDDEN2> mf;",
                     f"      const dn_mlp_desc d = {P}_DESC_INIT;",
                     "      if (md.load(&d) != DN_OK || mf.load(&d) != DN_OK) return 3;",
                     "      float xf[8]; double y; float yf;",
                     "      for (i = 0; i < n; ++i) xf[i] = (float)x[i];",
                     "      md.forward(x, &y); mf.forward(xf, &yf);",
                     "      printf(\"%.17g %.9g\\n\", y, (double)yf);",
                     "    }"]
        else:
            body += [f"    if (k == {k}) {{",
                     f"      dn_mlp_desc d = {P}_DESC_INIT; dn_mlp* m = NULL; double y; float yf, xf[8];",
                     "      if (dn_mlp_create(&d, &m) != DN_OK) return 3;",
                     "      for (i = 0; i < n; ++i) xf[i] = (float)x[i];",
                     "      dn_mlp_forward(m, x, &y, NULL); dn_mlp_forward_f(m, xf, &yf, NULL);",
                     "      printf(\"%.17g %.9g\\n\", y, (double)yf);",
                     "      dn_mlp_destroy(m);",
                     "    }"]
    body += ["  }", "  return 0;", "}"]
    src = tmp_path / ("prog.cpp" if cxx else "prog.c")
    src.write_text("\n".join(lines + body) + "\n")
    return src


def _run_on_random_inputs(exe, models, n: int) -> tuple[str, np.ndarray]:
    """Run a test program on n random inputs per model (stdin lines "k n_in x..."); returns its
    stdout and the torch float64 reference outputs in the same order."""
    inputs, refs = [], []
    for k, m in enumerate(models):
        x = random_inputs(m, n, seed=k)
        refs.append(torch_reference(m, x))
        inputs += [f"{k} {m.n_inputs} " + " ".join(f"{v:.17g}" for v in row) for row in x]
    proc = subprocess.run([str(exe)], input="\n".join(inputs) + "\n", capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout, np.concatenate(refs)


@pytest.mark.parametrize("language", ["c++17", "c99"])
def test_generated_headers_compile_and_match_torch(tmp_path, language):
    cxx = language == "c++17"
    models = [random_model(n, h, a, seed=500 + k) for k, (n, h, a) in enumerate(SHAPES)]
    src = _write_header_program(models, tmp_path, cxx)
    exe = compile_program([src], tmp_path / "prog", cxx=cxx, include_dirs=[tmp_path, *paths.include_dirs()],
                          libs=[] if cxx else [paths.shared_library()], std=language)
    stdout, ref = _run_on_random_inputs(exe, models, 100)
    got = np.array(stdout.split(), dtype=float).reshape(-1, 2)
    assert got.shape[0] == ref.shape[0]
    assert np.max(np.abs(got[:, 0] - ref)) <= DOUBLE_TOL
    assert np.max(np.abs(got[:, 1] - ref)) <= FLOAT_TOL


def _cpu_flags() -> set[str]:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


# Every backend of the header-only kernel (cpp/include/dampnet/kernel/backend.hpp), compiled here
# with its flags and DN_KERNEL_BACKEND (whatever the installed runtime was built with): what the
# CMake options DAMPNET_AVX512, DAMPNET_AVX2 and OFF select, and the scalar backend of
# microcontrollers on this host. "sse" passes no macro: the header's default on x86.
SIMD_PATHS = {
    "avx512": (["-mavx2", "-mfma", "-mavx512f", "-mavx512vl", "-mavx512dq", "-ffp-contract=off",
                "-DDN_KERNEL_BACKEND=avx512"], {"avx2", "fma", "avx512f", "avx512vl", "avx512dq"}),
    "avx2+fma": (["-mavx2", "-mfma", "-ffp-contract=off", "-DDN_KERNEL_BACKEND=avx2"], {"avx2", "fma"}),
    "sse": ([], set()),
    "scalar": (["-DDN_KERNEL_BACKEND=scalar"], set()),
}


def _torch_slope_and_curvature(model, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dy/dx0 and d2y/dx0^2 of torch_reference's forward by autograd, float64 (0 where x0 is
    clamped: the saturated model does not depend on it)."""
    torch = needs.need_module("torch")
    t0 = torch.as_tensor(x[:, 0], dtype=torch.float64).requires_grad_(True)
    t = torch.cat([t0[:, None], torch.as_tensor(x[:, 1:], dtype=torch.float64)], dim=1)
    t = torch.minimum(torch.maximum(t, torch.as_tensor(model.sat_lo)), torch.as_tensor(model.sat_hi))
    t = (t - torch.as_tensor(model.in_offset)) * torch.as_tensor(model.in_gain) + model.in_ymin
    act = torch.tanh if model.activation == "tanh" else torch.sigmoid
    layers = [(model.w1, model.b1)] + ([(model.w2, model.b2)] if model.w2 is not None else [])
    for w, b in layers:
        t = act(t @ torch.as_tensor(w).T + torch.as_tensor(b))
    y = ((t @ torch.as_tensor(model.w_out) + model.b_out) - model.out_ymin) / model.out_gain + model.out_offset
    (g,) = torch.autograd.grad(y.sum(), t0, create_graph=True)
    (c,) = torch.autograd.grad(g.sum(), t0, allow_unused=True)
    c = torch.zeros_like(g) if c is None else c
    return g.detach().numpy(), c.detach().numpy()


@pytest.mark.parametrize("isa", list(SIMD_PATHS))
def test_every_simd_path_matches_torch(tmp_path, isa):
    """Each SIMD path's float kernel (compile-time and run-time sizes, and forward_grad's
    value) within FLOAT_TOL (1e-5 of the force range) of the torch float64 reference, the
    double kernel within DOUBLE_TOL (1e-12), over the shapes of SHAPES with 20 % of the
    inputs beyond the saturation range. forward_grad_curv (the damper inverse's Halley steps):
    its value and slope forward_grad's bits, float and double; its slope and curvature in x0
    against torch's autograd (float within 1e-4, double 1e-9 of the largest over the samples;
    0 where x0 is clamped; NaN for two hidden layers, which it does not compute)."""
    flags, needs = SIMD_PATHS[isa]
    if not needs <= _cpu_flags():
        pytest.skip(f"this CPU does not run {isa}")
    models = [random_model(n, h, a, seed=700 + k) for k, (n, h, a) in enumerate(SHAPES)]
    lines = ["#include <stdio.h>", '#include "dampnet/mlp.hpp"']
    body = ["int main(void) {", '  printf("%s\\n", dampnet::kernel_isa());',
            "  int k, n, i; double x[8];", "  while (scanf(\"%d %d\", &k, &n) == 2) {",
            "    for (i = 0; i < n; ++i) if (scanf(\"%lf\", &x[i]) != 1) return 2;",
            "    float xf[8]; double y, yd, gd, yd2, gd2, cd; float yf, yr, yg, g, yc, gc, cc;",
            "    for (i = 0; i < n; ++i) xf[i] = (float)x[i];"]
    for k, m in enumerate(models):
        write_header(m, tmp_path / f"m{k}.h", prefix=f"m{k}")
        lines.append(f'#include "m{k}.h"')
        P = f"M{k}"
        body += [f"    if (k == {k}) {{",
                 f"      static dampnet::StaticMlp<double, {P}_N_INPUTS, {P}_N_HIDDEN1, {P}_N_HIDDEN2> md;",
                 f"      static dampnet::StaticMlp<float, {P}_N_INPUTS, {P}_N_HIDDEN1, {P}_N_HIDDEN2> mf;",
                 "      static dampnet::Mlp<float> mr;",
                 "      static dampnet::Mlp<double> mrd;",
                 f"      const dn_mlp_desc d = {P}_DESC_INIT;",
                 "      if (md.load(&d) != DN_OK || mf.load(&d) != DN_OK || mr.load(&d) != DN_OK || mrd.load(&d) != DN_OK) return 3;",
                 "      md.forward(x, &y); mf.forward(xf, &yf); mr.forward(xf, &yr);",
                 "      mr.forward_grad(xf, &yg, 0, &g);",
                 "      mr.forward_grad_curv(xf, &yc, 0, &gc, &cc);",
                 "      mrd.forward_grad(x, &yd, 0, &gd);",
                 "      mrd.forward_grad_curv(x, &yd2, 0, &gd2, &cd);",
                 "      if (!(yc == yg && gc == g && yd2 == yd && gd2 == gd)) return 4;",
                 "      printf(\"%.17g %.9g %.9g %.9g %.9g %.9g %.17g %.17g\\n\", y, (double)yf, (double)yr, (double)yg,",
                 "             (double)gc, (double)cc, gd, cd);",
                 "    }"]
    body += ["  }", "  return 0;", "}"]
    src = tmp_path / "prog.cpp"
    src.write_text("\n".join(lines + body) + "\n")
    exe = compile_program([src], tmp_path / "prog", cxx=True, include_dirs=[tmp_path, *paths.include_dirs()],
                          extra=flags)
    stdout, ref = _run_on_random_inputs(exe, models, 200)
    out = stdout.split("\n", 1)
    assert out[0] == isa  # the path these flags select
    got = np.array(out[1].split(), dtype=float).reshape(-1, 8)
    assert got.shape[0] == ref.shape[0]
    assert np.max(np.abs(got[:, 0] - ref)) <= DOUBLE_TOL
    for col in (1, 2, 3):
        assert np.max(np.abs(got[:, col] - ref)) <= FLOAT_TOL, (isa, col)
    row = 0
    for k, m in enumerate(models):
        x = random_inputs(m, 200, seed=k)
        g_ref, c_ref = _torch_slope_and_curvature(m, x)
        mine = got[row:row + len(x)]
        row += len(x)
        gs, cs = np.max(np.abs(g_ref)) + 1e-300, np.max(np.abs(c_ref)) + 1e-300
        assert np.max(np.abs(mine[:, 4] - g_ref)) <= 1e-4 * gs, (isa, k, "float slope")
        assert np.max(np.abs(mine[:, 6] - g_ref)) <= 1e-9 * gs, (isa, k, "double slope")
        if m.w2 is not None:  # two hidden layers: not computed
            assert np.all(np.isnan(mine[:, 5])) and np.all(np.isnan(mine[:, 7])), (isa, k)
            continue
        assert np.max(np.abs(mine[:, 5] - c_ref)) <= 1e-3 * cs, (isa, k, "float curvature")
        assert np.max(np.abs(mine[:, 7] - c_ref)) <= 1e-9 * cs, (isa, k, "double curvature")
        clamped = (x[:, 0] < m.sat_lo[0]) | (x[:, 0] > m.sat_hi[0])
        assert clamped.any() and np.all(mine[clamped, 5] == 0) and np.all(mine[clamped, 7] == 0), (isa, k)
