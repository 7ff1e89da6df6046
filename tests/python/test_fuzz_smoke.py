"""A CI-sized run of the libFuzzer harnesses of fuzz/ (model loading, dampers, the
quarter-car loop, all through the C ABI, under ASan + UBSan with every report fatal).

Each harness first replays its seed corpus fuzz/corpus/<harness>/ (which holds the
inputs of the bugs the fuzzers found, as regressions), then mutates it for a fixed
number of runs with a fixed seed. A harness aborts when the API breaks a promise
(non-finite output with a success status, state changed by a failed step, ...), so
a crash, a sanitizer report or a violated contract fails the test with the
harness's own report. The long runs (>= 1e7 executions each) are in fuzz/README.md.

clang with its libFuzzer runtime is a requirement (python/env.sh installs it): the
test fails without it, unless env.sh recorded why it could not install it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

import needs

from atheris_run import ran_all

from cbuild import BUILD, ROOT, run

HARNESSES = ("mlp", "damper", "loop")
CORPUS = ROOT / "fuzz" / "corpus"
RUNS = 10000  # mutations per harness after the corpus replay: about a second each on an idle core


@pytest.fixture(scope="session")
def fuzz_build() -> Path:
    """The harnesses built with clang into build/fuzz (incremental after the first time)."""
    clang = needs.need_tool("clang++")
    runtime = run([clang, "-print-file-name=libclang_rt.fuzzer-x86_64.a"]).stdout.strip()
    if not os.path.isfile(runtime):
        runtime = str(Path(run([clang, "-print-resource-dir"]).stdout.strip())
                      / "lib" / "linux" / "libclang_rt.fuzzer-x86_64.a")
    needs.need_file(runtime, "libclang-rt-14-dev", "clang's libFuzzer runtime")
    bdir = BUILD / "fuzz"
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    run(["cmake", "-S", ROOT, "-B", bdir, *gen, "-DCMAKE_CXX_COMPILER=" + clang,
         "-DCMAKE_C_COMPILER=" + (shutil.which("clang") or "clang"), "-DDAMPNET_BUILD_FUZZ=ON",
         "-DDAMPNET_BUILD_TESTS=OFF", "-DCMAKE_BUILD_TYPE=RelWithDebInfo",
         "-DCMAKE_UNITY_BUILD=ON"])  # the runtime's sources compiled as one: 23 -> 13 s of CPU
    run(["cmake", "--build", bdir, "--parallel", str(os.cpu_count() or 2),
         "--target", *[f"fuzz_{h}" for h in HARNESSES]])
    return bdir / "fuzz"


def _libfuzzer(exe: Path, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0",
               UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1")
    return subprocess.run([str(exe), *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300, env=env)


@pytest.mark.parametrize("harness", HARNESSES)
def test_fuzz_harness_short_run_finds_nothing(fuzz_build, harness, tmp_path):
    seeds = CORPUS / harness
    files = sorted(seeds.iterdir())
    assert 1 <= len(files) <= 60, f"the seed corpus {seeds} should hold a few dozen files"
    work = tmp_path / "corpus"  # new inputs go here (the first directory), never into the repo
    work.mkdir()
    proc = _libfuzzer(fuzz_build / f"fuzz_{harness}",
                      [f"-runs={RUNS}", "-seed=1", "-max_len=512", "-timeout=20",
                       "-rss_limit_mb=2048", f"-artifact_prefix={tmp_path}/", str(work), str(seeds)],
                      cwd=tmp_path)
    log = proc.stderr
    assert proc.returncode == 0, f"fuzz_{harness} failed (exit {proc.returncode}):\n{log[-6000:]}"
    assert "ERROR:" not in log and "runtime error" not in log, log[-6000:]
    # Every seed was replayed, then the mutation runs all ran.
    assert "INITED" in log and ran_all(log, RUNS), log[-3000:]
    assert not list(tmp_path.glob("crash-*")) and not list(tmp_path.glob("leak-*"))


@pytest.mark.parametrize("harness", HARNESSES)
def test_fuzz_regression_inputs_pass(fuzz_build, harness, tmp_path):
    """The corpus files replayed one by one (libFuzzer's plain execution mode): the
    inputs of the bugs found (regression-*) pass."""
    files = sorted((CORPUS / harness).iterdir())
    proc = _libfuzzer(fuzz_build / f"fuzz_{harness}", [str(f) for f in files], cwd=tmp_path)
    assert proc.returncode == 0, f"fuzz_{harness} failed on its corpus:\n{proc.stderr[-6000:]}"
    assert proc.stderr.count("Executed ") == len(files)
