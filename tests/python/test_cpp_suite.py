"""The C/C++ tests (tests/cpp, ctest) under ASan/UBSan, the installed CMake package
used by a separate consumer project, and the Eigen kernel against the plain one."""

from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

from cbuild import ROOT, run
from dampnet.model import MlpModel


@pytest.mark.slow(reason="builds the project and every C/C++ test under AddressSanitizer and UBSan (about 75 s of CPU at -Og, cached in build/tests-asan) and runs them all (30 s)")
def test_ctest_clean_under_address_and_undefined_sanitizers(asan_build):
    proc = subprocess.run(["ctest", "--output-on-failure", "--timeout", "600"], cwd=asan_build,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout[-8000:] + proc.stderr[-4000:]
    assert "100% tests passed" in proc.stdout
    # both folders of tests/cpp ran (each test is labelled with its folder)
    labels = proc.stdout.split("Label Time Summary:")[-1]
    assert re.search(r"^functional\s.*\d+ tests?", labels, re.M), proc.stdout[-3000:]
    assert re.search(r"^unit\s.*\d+ tests?", labels, re.M), proc.stdout[-3000:]
    # Sanitizer reports go to stderr of the failing test; none may appear.
    assert "runtime error" not in proc.stdout and "AddressSanitizer" not in proc.stdout


def test_no_allocation_in_a_plain_build(plain_build):
    """The no-allocation tests again without sanitizers: there malloc, calloc, realloc and
    the aligned allocators are interposed directly (under ASan the sanitizer's allocation
    hook counts them: the ctest run above). Each program first checks that its counter
    sees every entry point, then counts through the forward calls and loop steps (every
    damper, integrator, law and accel_feature mode)."""
    run(["cmake", "--build", plain_build, "--target", "test_no_alloc", "test_loop_no_alloc", "test_fullcar"])
    outs = {}
    for exe in ("test_no_alloc", "test_loop_no_alloc", "test_fullcar"):
        outs[exe] = out = run([plain_build / "tests" / "cpp" / exe]).stdout
        assert "NOT counted" not in out and "all checks passed" in out, out
    assert ("steps per accel_feature mode (implicit, linear, explicit): 432000 432000 432000"
            in outs["test_loop_no_alloc"])
    # the full car: 2 damper_eval x 3 accel_feature x 2 steering modes x 4000 steps
    assert "full car: allocations during 48000 steps: 0, errors 0" in outs["test_fullcar"]


def test_find_package_consumer_links_and_runs(installed_prefix, tmp_path):
    bdir = tmp_path / "consumer"
    run(["cmake", "-S", ROOT / "tests" / "consumer", "-B", bdir, f"-DCMAKE_PREFIX_PATH={installed_prefix}"])
    run(["cmake", "--build", bdir])
    default = MlpModel.load(ROOT / "export" / "dn_model_default.json")
    expected = default.predict(np.array([[0.1, 1.0, 2.0]]))[0]
    for exe in ("consumer_c", "consumer_shared"):
        out = run([bdir / exe]).stdout
        force = float(out.split(":")[-1].split("N")[0])
        assert abs(force - expected) <= 1e-9 * abs(expected) + 1e-9, out


def _outputs(build):
    out = run([build / "tests" / "cpp" / "dn_print_outputs"]).stdout.split()
    return np.array(out, dtype=float).reshape(-1, 4)


def test_eigen_kernel_agrees_with_plain_kernel(plain_build, eigen_build):
    plain, eigen = _outputs(plain_build), _outputs(eigen_build)
    assert plain.shape == eigen.shape and plain.shape[0] > 300
    force_range = 4000.0  # RandomModel's output scaling (tests/cpp/support/random_model.hpp)
    # Eigen sums in another order: equal to rounding, not bit for bit.
    assert np.max(np.abs(plain[:, 2] - eigen[:, 2])) <= 1e-12 * force_range
    assert np.max(np.abs(plain[:, 3] - eigen[:, 3])) <= 1e-5 * force_range
