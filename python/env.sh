#!/usr/bin/env bash
# Usage: bash python/env.sh COMMAND [ARGS...]   e.g. `bash python/env.sh dampnet demo`
# Sets up everything dampnet needs on a fresh machine, idempotently, then runs
# COMMAND inside the environment:
# Debian packages (Eigen, a C compiler is assumed), a virtual environment in
# .venv, the Python dependencies (torch pinned to the local CPU build), and
# the C++ core built into the package (editable install, incremental rebuild).
set -euo pipefail
DN_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$DN_ROOT"

dn_log() { printf '[dampnet setup] %s\n' "$*" >&2; }

# Debian packages: Eigen (optional dense kernel), Chromium (report check), clang and
# its libFuzzer runtime (the fuzz harnesses of fuzz/, run by tests/python/test_fuzz_smoke.py).
dn_apt_install() {  # dn_apt_install PKG... : install quietly when root; 1 when it could not
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    dn_log "installing Debian packages: $*"
    if [ -z "${dn_apt_updated:-}" ]; then
      apt-get update -qq >/dev/null 2>&1 || true
      dn_apt_updated=1
    fi
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null 2>&1 && return 0
    dn_log "warning: could not install $*; features that need them are skipped with a reason"
  else
    dn_log "warning: missing $* and not root; features that need them are skipped with a reason"
  fi
  return 1
}
# The libFuzzer runtime of the installed clang (the Debian package libclang-rt-N-dev).
dn_libfuzzer() {
  command -v clang++ >/dev/null 2>&1 || return 1
  [ -f "$(clang++ -print-resource-dir 2>/dev/null)/lib/linux/libclang_rt.fuzzer-x86_64.a" ] \
    || [ -f "$(clang++ -print-file-name=libclang_rt.fuzzer-x86_64.a 2>/dev/null)" ]
}
need_apt=()
[ -f /usr/include/eigen3/Eigen/Core ] || need_apt+=(libeigen3-dev)
command -v chromium >/dev/null 2>&1 || need_apt+=(chromium)
command -v clang++ >/dev/null 2>&1 || need_apt+=(clang)
# The Cortex-M cross build and its emulator (cpp/embedded/, tests/python/test_embedded.py):
# arm-none-eabi GCC with newlib, and QEMU's Arm system emulator (MPS2 boards).
command -v arm-none-eabi-gcc >/dev/null 2>&1 || need_apt+=(gcc-arm-none-eabi)
[ -f /usr/lib/arm-none-eabi/lib/libc_nano.a ] || need_apt+=(libnewlib-arm-none-eabi)
command -v qemu-system-arm >/dev/null 2>&1 || need_apt+=(qemu-system-arm)
if ((${#need_apt[@]})); then
  dn_apt_install "${need_apt[@]}" || true
fi
# The test of the fuzz harnesses fails without libFuzzer unless this marker says why
# it could not be installed here (removed again once it is).
dn_fuzz_marker=build/libfuzzer-unavailable.txt
if ! dn_libfuzzer && command -v clang++ >/dev/null 2>&1; then
  clang_major="$(clang++ -dumpversion 2>/dev/null | cut -d. -f1)"
  dn_apt_install "libclang-rt-${clang_major}-dev" || true
fi
if dn_libfuzzer; then
  rm -f "$dn_fuzz_marker"
else
  mkdir -p build
  echo "python/env.sh could not install clang and its libFuzzer runtime (libclang-rt-N-dev): not root, no apt-get, or the install failed" >"$dn_fuzz_marker"
fi

PY="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  dn_log "creating virtual environment in .venv"
  "$PY" -m venv .venv
fi
# shellcheck disable=SC1091
source .venv/bin/activate

# Build tools first (the editable install builds without isolation so that
# CMake's build/ directory is reused), then dampnet with its extras; torch is
# pinned in pyproject.toml to the local CPU build.
stamp=.venv/.dampnet-build-tools
if [ ! -f "$stamp" ]; then
  dn_log "installing build tools into .venv"
  python -m pip install -q --upgrade pip >/dev/null 2>&1
  python -m pip install -q scikit-build-core pybind11 cmake ninja 2> >(grep -v "^WARNING: Location" >&2)
  touch "$stamp"
fi
dn_log "building the C++ core and installing dampnet with its dependencies (first run: a few minutes)"
# pip's "Location ... is ignored" lines are about this machine's optional local mirrors: noise.
python -m pip install -q --no-build-isolation -e ".[train,test,bench]" 2> >(grep -v "^WARNING: Location" >&2)

if (($#)); then
  exec "$@"
fi
