"""The package's import graph: the layers contract in pyproject.toml ([tool.importlinter]) holds,
covers every module of python/dampnet (a new module outside every layer fails here), and no
modules import each other in a cycle (function-local imports count: they are imports)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
SOURCE = ROOT / "python"


@pytest.fixture(scope="module")
def graph():
    sys.path.insert(0, str(SOURCE))  # the source tree's package, not an installed copy
    try:
        return grimp.build_graph("dampnet", cache_dir=None)
    finally:
        sys.path.remove(str(SOURCE))


def cycles(graph) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    adj = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in sorted(graph.modules)}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in adj:
        if root in index:
            continue
        work = [(root, iter(adj[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(adj.get(w, ()))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on_stack.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        found.append(sorted(comp))
    return found


def test_the_layers_contract_holds():
    env = dict(os.environ, PYTHONPATH=str(SOURCE))
    lint_imports = Path(sys.executable).with_name("lint-imports")  # import-linter's command
    r = subprocess.run([str(lint_imports), "--config", str(ROOT / "pyproject.toml"), "--no-cache"],
                       cwd=ROOT, env=env, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "0 broken" in r.stdout


def test_no_import_cycles(graph):
    assert cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle():
    g = grimp.ImportGraph()
    for m in ("p", "p.a", "p.b", "p.c"):
        g.add_module(m)
    g.add_import(importer="p.a", imported="p.b")
    g.add_import(importer="p.b", imported="p.c")
    g.add_import(importer="p.c", imported="p.a")
    assert cycles(g) == [["p.a", "p.b", "p.c"]]


# ---- every module is in some layer ----

def package_modules(src: Path, root: str) -> list[str]:
    """The dotted names of the package's Python files (a package by its __init__.py)."""
    names = []
    for f in sorted((src / root).rglob("*.py")):
        parts = f.relative_to(src).with_suffix("").parts
        names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def layer_modules(contracts: list[dict]) -> set[str]:
    """Every module named in a layer of the layers contracts ("a | b", "a : b", "(a)" optional;
    a contract's containers prefix its layers' names)."""
    named = set()
    for c in contracts:
        if c.get("type") != "layers":
            continue
        boxes = c.get("containers") or [None]
        for layer in c["layers"]:
            for tail in (t.strip().strip("()") for t in re.split(r"[|:]", layer)):
                named.update(f"{box}.{tail}" if box else tail for box in boxes)
    return named


def uncovered(modules: list[str], contracts: list[dict], root: str) -> list[str]:
    """The modules no layer covers: neither named in one nor inside a package that is (the root
    package, the contracts' container, aside)."""
    named = layer_modules(contracts)
    return [m for m in modules
            if m != root and not any(m == n or m.startswith(n + ".") for n in named)]


def test_every_module_is_in_a_layer():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    modules = package_modules(SOURCE, config["root_package"])
    assert len(modules) > 100 and "dampnet.export.mcu" in modules and "dampnet.envelope.grid" in modules
    missing = uncovered(modules, config["contracts"], config["root_package"])
    assert missing == [], f"modules in no layer of [tool.importlinter] (pyproject.toml): {missing}"


def test_the_root_package_itself_imports_nothing(graph):
    """The one module the layers leave out, dampnet/__init__.py, names its API lazily (importlib
    on first use): it imports no dampnet module, so it cannot break a layer."""
    assert graph.find_modules_directly_imported_by("dampnet") == set()


def test_the_coverage_check_finds_an_uncovered_module():
    contracts = [{"type": "layers", "layers": ["p.cli", "p.a | (p.b)", "p.c : p.low"]},
                 {"type": "layers", "containers": ["p.d"], "layers": ["x", "y"]},
                 {"type": "independence", "modules": ["p.e", "p.f"]}]
    modules = ["p", "p.cli", "p.a", "p.a.deep.m", "p.b", "p.c", "p.low", "p.lower", "p.d", "p.d.x", "p.d.y",
               "p.d.z", "p.e"]
    # p.lower only shares a prefix with p.low; p.d (the container) and p.d.z are in no layer;
    # an independence contract names no layer
    assert uncovered(modules, contracts, "p") == ["p.lower", "p.d", "p.d.z", "p.e"]


def test_package_modules_names_files_and_packages(tmp_path):
    for f in ("q/__init__.py", "q/a.py", "q/sub/__init__.py", "q/sub/b.py", "q/data.txt"):
        (tmp_path / f).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / f).write_text("")
    assert package_modules(tmp_path, "q") == ["q", "q.a", "q.sub", "q.sub.b"]
