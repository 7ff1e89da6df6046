"""Where the installed C library, headers and default model are (for compiling C programs against
dampnet, and for the MODEL spelled "default")."""

from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent
_SRC_ROOT = _PKG.parent.parent  # the source tree, in an editable install


def include_dirs() -> list[Path]:
    """Directories holding dampnet/dampnet.h (installed copy first, then the source tree)."""
    dirs = [d for d in (_installed_root() / "include", _SRC_ROOT / "cpp" / "include")
            if (d / "dampnet" / "dampnet.h").is_file()]
    if not dirs:
        raise FileNotFoundError(f"dampnet/dampnet.h not found in {_installed_root() / 'include'}: "
                                "reinstall dampnet (pip install, or bash python/env.sh in a source tree)")
    return dirs[:1]


def shared_library() -> Path:
    """The shared C library (libdampnet.so) installed with the Python package."""
    for d in (_installed_root() / "lib",):
        for name in ("libdampnet.so", "libdampnet.dylib", "dampnet.dll"):
            if (d / name).is_file():
                return d / name
    raise FileNotFoundError(f"libdampnet shared library not found in {_installed_root() / 'lib'}: "
                            "reinstall dampnet (pip install, or bash python/env.sh in a source tree)")


def _installed_root() -> Path:
    """The directory the compiled extension was installed into (site-packages/dampnet)."""
    from dampnet import _core

    return Path(_core.__file__).resolve().parent


def default_model_path() -> Path:
    """export/dn_model_default.json: installed with the package, or in the source tree."""
    candidates = [_SRC_ROOT / "export" / "dn_model_default.json"]
    try:
        candidates.insert(0, _installed_root() / "include" / "dn_model_default.json")
    except Exception:  # the extension not importable: the source tree only
        pass
    for p in candidates:
        if p.is_file():
            return p
    raise FileNotFoundError("dn_model_default.json not found (looked in: "
                            + ", ".join(str(c) for c in candidates) + ")")
