"""python/dampnet/_core.pyi, the typed stub of the pybind11 module, against the built module
(mypy.stubtest): every public name of dampnet._core must be in the stub, consistent with it
(classes, properties, metaclass, final-ness), and the stub must type-check.

stubtest runs on a copy of the stub in a temporary stub-only package, so mypy reads the
stub alone (not the rest of python/dampnet) and leaves no cache in the tree.

The damper's states (dampnet.h DN_DAMPER_STATE_LIST) are DamperInput fields; a state added by
dampnet.h's recipe needs no stub line: the copy gets a DamperInput attribute for each state the
stub lacks (`with_damper_states`; the stub's own lines document the states it knows).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from cbuild import ROOT

STUB = ROOT / "python" / "dampnet" / "_core.pyi"


def with_damper_states(stub: str) -> str:
    """The stub with a DamperInput attribute (a float) for each damper state it does not declare."""
    from dampnet import _core

    start = stub.index("class DamperInput(")
    end = stub.index("    def __init__(self) -> None: ...", start)
    body = stub[start:end]
    extra = "".join(f"    {name}: float  # {_core.DAMPER_STATES[name][4]} [{_core.DAMPER_STATES[name][0]}]\n"
                    for name in _core.DAMPER_STATES if not re.search(rf"^    {name}:", body, re.M))
    return stub[:end] + extra + stub[end:]


def test_a_damper_state_the_stub_lacks_is_declared_from_the_registry():
    from dampnet import _core

    stub = STUB.read_text()
    last = list(_core.DAMPER_STATES)[-1]
    shorter = remove(stub, rf"    {last}:")
    assert shorter != stub
    assert with_damper_states(shorter).count(f"\n    {last}: float") == 1


def stubtest(stub_text: str, tmp_path: Path) -> subprocess.CompletedProcess:
    pkg = tmp_path / "stubs" / "dampnet"
    pkg.mkdir(parents=True)
    (pkg / "__init__.pyi").write_text("")
    (pkg / "_core.pyi").write_text(with_damper_states(stub_text))
    config = tmp_path / "mypy.ini"
    config.write_text(f"[mypy]\nmypy_path = {pkg.parent}\ncache_dir = {tmp_path / 'cache'}\n")
    return subprocess.run([sys.executable, "-m", "mypy.stubtest", "dampnet._core", "--concise",
                           "--mypy-config-file", str(config)],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)


def test_the_stub_matches_the_built_module(tmp_path):
    proc = stubtest(STUB.read_text(), tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def remove(stub: str, pattern: str) -> str:
    """The stub without the lines of one definition (its first line matches pattern)."""
    out, lines, skipping, indent = [], stub.splitlines(), False, 0
    for line in lines:
        depth = len(line) - len(line.lstrip())
        if skipping and line.strip() and depth <= indent and not line.lstrip().startswith(("@", ")")):
            skipping = False
        if not skipping and re.match(pattern, line):
            skipping, indent = True, depth
            while out and out[-1].strip().startswith("@"):  # its decorators
                out.pop()
            continue
        if not skipping:
            out.append(line)
    return "\n".join(out) + "\n"


def test_a_name_missing_from_the_stub_fails(tmp_path):
    # one of each kind: a function, a registry, a class member (not a damper state: those are
    # declared from the registry), a whole class
    stub = STUB.read_text()
    for pattern in (r"def check_vehicle\(", r"STEP_OUTPUT_FIELDS:", r"    temperature:", r"class StepReport\("):
        shorter = remove(stub, pattern)
        assert shorter != stub, pattern
        stub = shorter
    stub = stub.replace("-> StepReport:", "-> Any:")  # its uses, so the stub still type-checks
    proc = stubtest(stub, tmp_path)
    assert proc.returncode != 0
    for name in ("check_vehicle", "STEP_OUTPUT_FIELDS", "DamperInput.temperature", "StepReport"):
        assert re.search(rf"dampnet\._core\.{re.escape(name)} is not present in stub", proc.stdout), \
            (name, proc.stdout)
