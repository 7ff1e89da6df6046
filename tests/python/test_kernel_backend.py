"""The MLP kernel's backend is chosen in one place (cpp/include/dampnet/kernel/backend.hpp) from
DN_KERNEL_BACKEND, which CMake derives from its options; the options are obeyed.

* Configured with each combination of DAMPNET_AVX2, DAMPNET_AVX512, DAMPNET_NATIVE and
  DAMPNET_USE_EIGEN, a translation unit of the build (tests/cpp/unit/print_backend.cpp) gets the
  backend those options name: -march=native with DAMPNET_AVX512=OFF gets avx2, never the
  AVX-512 kernel the compiler flags would allow. (A build this CPU cannot run is checked by the
  backend's name compiled into the binary.)
* Without DN_KERNEL_BACKEND the header picks sse on x86 whatever the flags allow; a backend the
  flags cannot compile, or an unknown name, stops the compile with a message naming the flags."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from cbuild import ROOT, cmake_build

INCLUDE = ROOT / "cpp" / "include"


def _cpu_flags() -> set[str]:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


CPU = _cpu_flags()
HAS_AVX2 = {"avx2", "fma"} <= CPU
HAS_AVX512 = HAS_AVX2 and {"avx512f", "avx512vl", "avx512dq"} <= CPU

# (build name, CMake options, the backend's kernel_isa() expected on this machine, runs here)
CASES = [
    ("default", [], "avx2+fma" if HAS_AVX2 else "sse", True),
    ("avx2-off", ["DAMPNET_AVX2=OFF"], "sse", True),
    ("native", ["DAMPNET_NATIVE=ON", "DAMPNET_AVX512=OFF"], "avx2+fma" if HAS_AVX2 else "sse", True),
    ("native-avx512-auto", ["DAMPNET_NATIVE=ON", "DAMPNET_AVX512=AUTO"],
     "avx512" if HAS_AVX512 else ("avx2+fma" if HAS_AVX2 else "sse"), True),
    ("avx512-on", ["DAMPNET_AVX2=ON", "DAMPNET_AVX512=ON"], "avx512", HAS_AVX512),
]


@pytest.mark.parametrize("name,options,expected,runs", CASES, ids=[c[0] for c in CASES])
def test_cmake_options_choose_the_backend(name, options, expected, runs):
    if "avx512" in name and not HAS_AVX2:
        pytest.skip("not an x86-64 machine with AVX2")
    bdir = cmake_build(f"backend-{name}", "DAMPNET_BUILD_TESTS=ON", "CMAKE_BUILD_TYPE=Release",
                       *[o for o in options], target="dn_print_backend")
    exe = bdir / "tests" / "cpp" / "dn_print_backend"
    assert f"dn-kernel-backend:{expected};".encode() in exe.read_bytes()
    if runs:
        out = subprocess.run([exe], capture_output=True, text=True, check=True).stdout
        assert out == f"kernel_isa {expected}\n"


def test_eigen_option_chooses_the_eigen_backend():
    if not Path("/usr/include/eigen3/Eigen/Core").is_file():
        pytest.skip("Eigen's headers (libeigen3-dev) not installed")
    bdir = cmake_build("backend-eigen", "DAMPNET_BUILD_TESTS=ON", "DAMPNET_USE_EIGEN=ON",
                       "CMAKE_BUILD_TYPE=Release", target="dn_print_backend")
    out = subprocess.run([bdir / "tests" / "cpp" / "dn_print_backend"], capture_output=True, text=True,
                         check=True).stdout
    assert out == "kernel_isa eigen\n"


def _compile(tmp_path: Path, flags: list[str]) -> subprocess.CompletedProcess:
    src = tmp_path / "p.cpp"
    src.write_text('#include <cstdio>\n#include "dampnet/mlp.hpp"\n'
                   'int main() { std::printf("%s\\n", dampnet::kernel_isa()); return 0; }\n')
    return subprocess.run(["g++", "-std=c++17", "-O1", *flags, f"-I{INCLUDE}", str(src), "-o", str(tmp_path / "p")],
                          capture_output=True, text=True)


@pytest.mark.skipif(not HAS_AVX2, reason="not an x86-64 machine with AVX2")
def test_header_default_ignores_wider_compiler_flags(tmp_path):
    """-march=native (or -mavx2) without DN_KERNEL_BACKEND: the SSE backend, not the widest one."""
    proc = _compile(tmp_path, ["-march=native"])
    assert proc.returncode == 0, proc.stderr
    out = subprocess.run([tmp_path / "p"], capture_output=True, text=True, check=True).stdout
    assert out == "sse\n"


@pytest.mark.parametrize("flags,message", [
    (["-DDN_KERNEL_BACKEND=avx2"], "the compiler flags do not support this backend"),
    (["-mavx2", "-mfma", "-DDN_KERNEL_BACKEND=avx512"], "the compiler flags do not support this backend"),
    (["-DDN_KERNEL_BACKEND=neon"], "one of scalar, sse, avx2, avx512, eigen"),
    (["-DDN_KERNEL_BACKEND=sse", "-DDAMPNET_USE_EIGEN"], "DAMPNET_USE_EIGEN is defined but DN_KERNEL_BACKEND"),
], ids=["avx2-without-flags", "avx512-without-flags", "unknown", "eigen-conflict"])
def test_header_refuses_a_backend_the_flags_cannot_build(tmp_path, flags, message):
    proc = _compile(tmp_path, flags)
    assert proc.returncode != 0
    assert message in proc.stderr
