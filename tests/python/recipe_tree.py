"""A recipe applied the way a developer applies it: its documented edit made to a copy of the
tree, the copy built, and the copy's own tests run against it (issue 52 item 5: a recipe proved
through test-only hooks never takes the developer's path, and the tests that listed features by
hand failed only on that path).

- `doc_block(section)`: the python code block of docs/recipes.md's `## section` (a whole recipe,
  run as written from a test, or appended to its registry module in a copy);
- `state_recipe_rows(text)`: the example rows of dn_xmacro.h's stateful-feature recipe comment,
  read from the comment itself (so the recipe's text is what is tested), with the list each
  step names;
- `apply_rows(text, rows)`: the header with each row appended to its list, as the recipe says;
- `copy_tree(dest)`: the tree's files (tracked and new, not ignored: what a clone plus the
  developer's edits holds) under dest;
- `CopyEnv`: a Python environment importing the copy's `dampnet` and nothing of this tree's (a
  fresh venv whose .pth names the copy's python/ and borrows this .venv's libraries), and
  `build_core(copy)`: the copy's `dampnet._core`, built from its own headers into its package.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from cbuild import ROOT

#: what a copy holds: enough to build the runtime, the module, the FMU and the firmware, and to
#: run the Python tests (bench/ for the firmware lab, export/ for the default model)
COPIED = ("CMakeLists.txt", "CMakePresets.json", "pyproject.toml", "cmake", "cpp", "python", "tests", "bench",
          "docs", "examples", "export")


RECIPES_DOC = ROOT / "docs" / "recipes.md"


def doc_block(section: str) -> str:
    """The first ```python block under `## section` of docs/recipes.md."""
    text = RECIPES_DOC.read_text(encoding="utf-8")
    part = text.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
    m = re.search(r"```python\n(.*?)```", part, re.S)
    assert m, f"no python block under '## {section}' in {RECIPES_DOC}"
    return m.group(1)


def run_doc_block(section: str) -> dict:
    """docs/recipes.md's `section` block run as written, as a user's module; its namespace."""
    namespace: dict = {"__name__": f"recipe_{section.lower().replace(' ', '_')}"}
    exec(compile(doc_block(section), str(RECIPES_DOC), "exec"), namespace)
    return namespace


def _comment_lines(text: str, start: str) -> list[str]:
    """The lines of the /* ... */ comment holding `start`, without their leading ' * '."""
    i = text.index(start)
    j = text.index("*/", i)
    return [re.sub(r"^\s*\*? ?", "", ln) for ln in text[text.rindex("/*", 0, i):j].splitlines()]


def state_recipe_rows(header_text: str) -> list[tuple[str, str]]:
    """[(list macro, X(...) row)] for the recipe's steps 1..4, in order: each step's line names
    its list ("N. DN_..._LIST: ...") and its example row follows (an X( line and its
    continuation lines, until the parentheses close)."""
    lines = _comment_lines(header_text, "Recipe: a new stateful feature")
    rows: list[tuple[str, str]] = []
    current, row, depth = None, [], 0
    for ln in lines:
        step = re.match(r"\s*(\d)\. (DN_\w+)", ln)
        if step and not row:
            current = step.group(2)
            continue
        s = ln.strip()
        if not row and s.startswith("X(") and current:
            row, depth = [s], 0
        elif row:
            row.append(s)
        else:
            continue
        depth += s.count("(") - s.count(")")
        if depth == 0:
            rows.append((current, " ".join(row)))
            row, current = [], None
    return rows


def apply_rows(header_text: str, rows: list[tuple[str, str]]) -> str:
    """header_text with each row appended at the end of its list's #define (a continuation line)."""
    lines = header_text.split("\n")
    for macro, row in rows:
        start = next((i for i, ln in enumerate(lines) if ln.startswith(f"#define {macro}(X)")), None)
        if start is None:
            raise ValueError(f"the recipe names {macro}, which the header does not define")
        end = start
        while lines[end].rstrip().endswith("\\"):
            end += 1
        lines[end] = lines[end].rstrip() + " \\"
        lines.insert(end + 1, f"  {row}")
    return "\n".join(lines)


def copy_tree(dest: Path) -> Path:
    """This tree's files (git's tracked and untracked-but-not-ignored: a clone with the working
    tree's edits) under dest, COPIED's folders only; returns dest."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z", "--", *COPIED], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout.split("\0")
    for rel in filter(None, files):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    return dest


def build_core(copy: Path, log: Path) -> Path:
    """The copy's dampnet._core, built by its own CMakeLists from its own headers (the module's
    options as pyproject.toml's [tool.scikit-build.cmake.define]; -O0: the copy's tests check
    registries and results, not speed, and an optimised build of the module takes a minute more;
    a unity build: each target's sources compiled as one, pybind11's headers parsed once, 22 s of
    CPU against 60 s), placed into the copy's python/dampnet; returns the module's path."""
    import pybind11

    bdir = copy / "build" / "core"
    so_name = "_core" + sysconfig.get_config_var("EXT_SUFFIX")
    cmd = ["cmake", "-S", str(copy), "-B", str(bdir), "-DDAMPNET_BUILD_PYTHON=ON", "-DDAMPNET_BUILD_TESTS=OFF",
           "-DBUILD_SHARED_LIBS=OFF", "-DDAMPNET_MAX_HIDDEN=384", "-DCMAKE_BUILD_TYPE=Debug",
           "-DCMAKE_C_FLAGS_DEBUG=-O0", "-DCMAKE_CXX_FLAGS_DEBUG=-O0", "-DCMAKE_UNITY_BUILD=ON",
           f"-Dpybind11_DIR={pybind11.get_cmake_dir()}",
           f"-DPython_EXECUTABLE={sys.executable}"]
    with open(log, "w") as out:
        for step in (cmd, ["cmake", "--build", str(bdir), "--target", "_core", "--parallel", "2"]):
            proc = subprocess.run(step, stdout=out, stderr=subprocess.STDOUT, timeout=900)
            assert proc.returncode == 0, f"{' '.join(step)} failed; its output: {log}"
    built = next(bdir.rglob(so_name), None)
    assert built is not None, f"{so_name} not found under {bdir}"
    target = copy / "python" / "dampnet" / so_name
    shutil.copy2(built, target)
    return target


@dataclass(frozen=True)
class CopyEnv:
    """A fresh venv (no pip) that imports the copy's dampnet: its .pth names the copy's python/
    first, then this .venv's site-packages for numpy, pytest and the rest. A directory named in a
    .pth is only appended to sys.path, its own .pth files are not run, so this tree's editable
    install (a .pth hook in that site-packages) never loads (as tests/python/wheel_env.py)."""
    copy: Path
    python: Path

    @classmethod
    def make(cls, copy: Path, venv: Path) -> "CopyEnv":
        subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
        python = venv / "bin" / "python"
        site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                              capture_output=True, text=True, check=True).stdout.strip()
        (Path(site) / "dampnet_copy.pth").write_text(f"{copy / 'python'}\n{sysconfig.get_paths()['purelib']}\n")
        return cls(copy, python)

    @property
    def env(self) -> dict:
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTEST_XDIST_WORKER",
                                                                "PYTEST_CURRENT_TEST", "PYTEST_ADDOPTS")}
        env["PATH"] = f"{self.python.parent}{os.pathsep}{env.get('PATH', '')}"
        return env

    def run(self, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
        """python ARGS in the copy's root."""
        return subprocess.run([str(self.python), *args], cwd=self.copy, env=self.env, capture_output=True, text=True,
                              timeout=timeout)
