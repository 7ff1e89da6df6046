"""python/dampnet/_core.pyi, the typed stub of the pybind11 module, against the built module
(mypy.stubtest): every public name of dampnet._core must be in the stub, consistent with it
(classes, properties, metaclass, final-ness), and the stub must type-check.

stubtest runs on a copy of the stub in a temporary stub-only package, so mypy reads the
stub alone (not the rest of python/dampnet) and leaves no cache in the tree.

The parts of the stub that dampnet.h's X-macros define (DamperInput's fields, Damper.forces's
optional arrays) are generated from the built module's registries (tests/python/core_stub.py); a
stub behind them fails here naming the command that rewrites it (issue 52: the stub never gained
a state added by dampnet.h's recipe, because this test patched its own copy).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import core_stub
from cbuild import ROOT

STUB = ROOT / "python" / "dampnet" / "_core.pyi"


def test_the_generated_parts_of_the_stub_are_up_to_date():
    """Cost: 0.1 s."""
    text = STUB.read_text()
    assert core_stub.generated(text) == text, \
        f"{STUB} is behind dampnet._core's registries: run `python tests/python/core_stub.py`"


def test_a_field_added_by_the_recipe_changes_the_generated_stub(monkeypatch):
    """The recipe's step 2 (an appended dn_damper_input field, here probe_lag) makes the check above fail
    until the stub is rewritten, and the rewrite declares it in both places. Cost: 0.05 s."""
    from dampnet import _core

    # a field no registry has (the recipe's own example, x_lag, is in a tree the recipe was applied
    # to: tests/python/test_state_recipe.py runs this file there)
    assert "probe_lag" not in _core.DAMPER_INPUT_FIELDS
    fields = {**_core.DAMPER_INPUT_FIELDS, "probe_lag": "relative displacement after a first-order lag [m]"}
    monkeypatch.setattr(_core, "DAMPER_INPUT_FIELDS", fields)
    text = STUB.read_text()
    new = core_stub.generated(text)
    assert new != text
    assert "    probe_lag: float  # relative displacement after a first-order lag [m]\n" in new
    assert "        probe_lag: npt.ArrayLike = ...,\n" in new
    assert core_stub.generated(new) == new


def stubtest(stub_text: str, tmp_path: Path) -> subprocess.CompletedProcess:
    pkg = tmp_path / "stubs" / "dampnet"
    pkg.mkdir(parents=True)
    (pkg / "__init__.pyi").write_text("")
    (pkg / "_core.pyi").write_text(stub_text)
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
    # one of each kind: a function, a registry, a class member, a whole class
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
