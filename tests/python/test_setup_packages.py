"""A fresh machine passes: python/env.sh installs every Debian package by name from one
explicit list (python/debian-packages.txt), every external tool the suite calls is covered
by it, and a missing one fails naming its package (tests/python/needs.py)."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

import needs
import firmware_lab as embedded  # bench/firmware_lab.py

ROOT = needs.ROOT
#: where programs are called from: the package, the tests, the benchmarks, the examples, the fuzzers
SOURCE_DIRS = ("python", "tests", "bench", "examples", "fuzz")
CALL = re.compile(r"""(?:shutil\.which|which|need_tool)\(\s*"([^"]+)"\)|\b(?:_?run|Popen|check_output|check_call)\(\s*\[\s*"([^"]+)\"""")


def _called_programs() -> dict[str, list[str]]:
    """Every program named literally in a which() or as a subprocess' first word -> where."""
    found: dict[str, list[str]] = {}
    for d in SOURCE_DIRS:
        for path in sorted((ROOT / d).rglob("*.py")):
            for m in CALL.finditer(path.read_text(encoding="utf-8")):
                found.setdefault(m.group(1) or m.group(2), []).append(str(path.relative_to(ROOT)))
    return found


def _installed(pkg: str) -> bool:
    proc = subprocess.run(["dpkg-query", "-W", "-f=${db:Status-Status}", pkg], capture_output=True, text=True)
    return proc.stdout.strip() == "installed"


def test_the_list_is_what_env_sh_installs():
    script = (ROOT / "python" / "env.sh").read_text()
    assert "python/debian-packages.txt" in script and "dpkg-query" in script
    # no package chosen by probing for a binary ("command -v X || need X")
    assert not re.search(r"command -v \S+[^\n]*\|\|\s*need_apt", script)
    pkgs = needs.debian_packages()
    assert len(pkgs) == len(set(pkgs)), "a package is listed twice"
    assert "libstdc++-arm-none-eabi-dev" in pkgs  # the cross C++ headers a fresh machine lacked


def test_every_tool_the_suite_calls_is_covered_by_the_list():
    pkgs = set(needs.debian_packages())
    called = _called_programs()
    assert {"arm-none-eabi-gcc", "qemu-system-arm", "chromium", "clang++", "cmake"} <= set(called)
    unknown = {prog: where for prog, where in called.items()
               if prog not in needs.TOOLS and prog not in needs.PYPI_TOOLS and prog not in needs.ALTERNATIVES
               and prog not in NOT_PROGRAMS}
    assert not unknown, ("programs called but not in tests/python/needs.TOOLS (add each with its Debian "
                         f"package, and the package to python/debian-packages.txt): {unknown}")
    for tool in needs.TOOLS:
        assert needs.package_of(tool) in pkgs | needs.ESSENTIAL, f"{tool}: its package {needs.package_of(tool)} is not in the list"
    assert set(needs.ALTERNATIVES.values()) <= set(needs.TOOLS)


#: first words of lists the pattern matches that are not programs (a test helper's effect names,
#: bench/real_data.py's dataset names)
NOT_PROGRAMS = {"friction", "gas_spring", "utfsm"}


def test_every_listed_package_is_installed():
    missing = [p for p in needs.debian_packages() if not _installed(p)]
    assert not missing, ("Debian packages of python/debian-packages.txt not installed: "
                         f"{' '.join(missing)} (python/env.sh installs them; as root: apt-get install "
                         f"{' '.join(missing)})")


@pytest.mark.parametrize("tool", sorted(needs.TOOLS))
def test_every_tool_is_here(tool):
    assert needs.need_tool(tool)


def test_the_cross_compiler_has_its_cxx_headers():
    err = needs.cross_cxx_headers_error()
    assert err is None, err
    assert embedded.toolchain_missing() is None


def test_a_missing_tool_fails_naming_its_package(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing found
    with pytest.raises(pytest.fail.Exception, match="Debian package qemu-system-arm"):
        needs.need_tool("qemu-system-arm")
    with pytest.raises(pytest.fail.Exception, match="Debian package gcc-arm-none-eabi"):
        needs.need_tool("arm-none-eabi-nm")  # a dependency's tool: the listed package is named
    assert "gcc-arm-none-eabi" in embedded.toolchain_missing()
    with pytest.raises(pytest.fail.Exception, match=r"\[test\] extra"):
        needs.need_module("dampnet_no_such_module")


def test_toolchain_missing_names_the_cross_headers_package(tmp_path, monkeypatch):
    """A cross g++ without its C++ headers (simulated: a wrapper that cannot find <cstdint>)
    is reported with the package that brings them, not as a build error later."""
    fake = tmp_path / "bin"
    fake.mkdir()
    real_gxx = needs.need_tool("arm-none-eabi-g++")
    (fake / "arm-none-eabi-g++").write_text(
        f"#!/bin/sh\nexec {real_gxx} -nostdinc++ \"$@\"\n")
    (fake / "arm-none-eabi-g++").chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake}:{os.environ['PATH']}")
    why = embedded.toolchain_missing()
    assert why is not None and "libstdc++-arm-none-eabi-dev" in why, why
