#!/usr/bin/env bash
# Build and run the soak (bench/soak.cpp): 1e9 steps by default, results in
# build/soak/ (windows CSV, summary). A benchmark, not a test: minutes of one core.
# Usage: bash bench/soak.sh [dn_soak options...]   e.g. bash bench/soak.sh --steps 1e7
# The runtime is compiled in (static, -O3) with the same SIMD flags as the default
# build (AVX2+FMA when this machine runs them, -ffp-contract=off), like `dampnet bench`.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$root/build/soak"
mkdir -p "$out"
cxx="${CXX:-g++}"
isa=""
if grep -qw avx2 /proc/cpuinfo && grep -qw fma /proc/cpuinfo; then isa="-mavx2 -mfma -ffp-contract=off -DDN_KERNEL_BACKEND=avx2"; fi
# shellcheck disable=SC2086
"$cxx" -std=c++17 -O3 -DNDEBUG -DDN_STATIC $isa -I"$root/cpp/include" -I"$root/export" \
  "$root/bench/soak.cpp" "$root"/cpp/src/*.cpp -o "$out/dn_soak"
cd "$out"
nice -n 10 ./dn_soak --csv "$out/soak_windows.csv" "$@" | tee "$out/soak_summary.txt"
