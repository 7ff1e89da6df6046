"""What the suite needs from outside Python, and one way to ask for it.

Every external program a test (or a command it runs) calls is in TOOLS with the Debian package
that brings it; every package is in python/debian-packages.txt, which python/env.sh installs by
name. A test that needs a tool calls `need_tool`: a missing one fails the test naming the
package, never a silent skip. tests/python/test_setup_packages.py keeps TOOLS, the package
list and the sources' calls in step.
"""

from __future__ import annotations

import importlib
import shutil
import subprocess
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
DEBIAN_LIST = ROOT / "python" / "debian-packages.txt"

#: external programs the suite, the commands it runs and the benchmarks call -> Debian package
TOOLS = {
    "cc": "build-essential", "c++": "build-essential", "gcc": "build-essential",
    "g++": "build-essential", "make": "build-essential", "ldd": "libc-bin", "dpkg-query": "dpkg",
    "chromium": "chromium",
    "clang": "clang", "clang++": "clang",
    "arm-none-eabi-gcc": "gcc-arm-none-eabi", "arm-none-eabi-g++": "gcc-arm-none-eabi",
    "arm-none-eabi-nm": "binutils-arm-none-eabi", "arm-none-eabi-objdump": "binutils-arm-none-eabi",
    "arm-none-eabi-c++filt": "binutils-arm-none-eabi",
    "qemu-system-arm": "qemu-system-arm",
    "valgrind": "valgrind",
    # binutils (with build-essential): the code footprint (dampnet.latency.footprint)
    "nm": "binutils", "objdump": "binutils", "readelf": "binutils", "c++filt": "binutils",
    # bench/compare_speed.py: which commit each side is, and each tree's set-up
    "git": "git", "bash": "bash",
}
#: programs that come from PyPI with the build tools python/env.sh installs into .venv
PYPI_TOOLS = {"cmake": "cmake", "ctest": "cmake", "ninja": "ninja"}
#: Debian packages that come with another one of the list (a dependency), not listed themselves
DEPENDENCIES = {"binutils-arm-none-eabi": "gcc-arm-none-eabi", "binutils": "build-essential"}
#: Debian's essential packages: on every Debian system, never listed
ESSENTIAL = {"dpkg", "libc-bin", "bash"}
#: names tried only as alternatives to a listed tool (another distribution's Chromium)
ALTERNATIVES = {"chromium-browser": "chromium", "google-chrome": "chromium"}


def debian_packages() -> list[str]:
    """The package names of python/debian-packages.txt (first word of each non-comment line)."""
    names = []
    for line in DEBIAN_LIST.read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            names.append(line.split()[0])
    return names


def package_of(tool: str) -> str:
    """The Debian package (of the list) that brings `tool`."""
    pkg = TOOLS[tool]
    return DEPENDENCIES.get(pkg, pkg)


def missing_message(tool: str) -> str:
    if tool in PYPI_TOOLS:
        return (f"{tool} not found: it comes from the PyPI package {PYPI_TOOLS[tool]}, which python/env.sh "
                "installs into .venv (run the suite as `bash python/env.sh pytest`)")
    return (f"{tool} not found: install the Debian package {package_of(tool)} (python/env.sh installs "
            "every package of python/debian-packages.txt; as root: apt-get install "
            f"{package_of(tool)})")


def need_tool(tool: str) -> str:
    """The path of `tool`; the calling test fails naming its package when it is missing."""
    path = shutil.which(tool)
    if path is None:
        pytest.fail(missing_message(tool), pytrace=False)
    return path


def need_file(path: str | Path, package: str, what: str) -> Path:
    """`path` if it exists; the calling test fails naming the Debian package otherwise."""
    p = Path(path)
    if not p.exists():
        pytest.fail(f"{what} ({p}) not found: install the Debian package {package} (python/env.sh "
                    "installs every package of python/debian-packages.txt)", pytrace=False)
    return p


def need_module(name: str, extra: str = "test") -> ModuleType:
    """The imported Python module; the test fails naming dampnet's extra that installs it."""
    try:
        return importlib.import_module(name)
    except ImportError as e:
        pytest.fail(f"Python module {name} not importable ({e}): it is in dampnet's [{extra}] extra, "
                    f"which python/env.sh installs (pip install -e '.[{extra}]')", pytrace=False)


def cross_cxx_headers_error() -> str | None:
    """None if arm-none-eabi-g++ compiles `#include <cstdint>`; else why, naming the package."""
    need_tool("arm-none-eabi-g++")
    proc = subprocess.run(["arm-none-eabi-g++", "-x", "c++", "-std=c++17", "-c", "-o", "/dev/null", "-"],
                          input="#include <cstdint>\nstd::uint32_t x = 1;\n", capture_output=True,
                          text=True, timeout=120)
    if proc.returncode == 0:
        return None
    return ("arm-none-eabi-g++ cannot compile #include <cstdint>: install the Debian package "
            f"libstdc++-arm-none-eabi-dev (python/env.sh installs it)\n{proc.stderr[-2000:]}")
