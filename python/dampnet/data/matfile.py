"""MATLAB .mat files (v4 to v7.2) read by scipy in a child process.

scipy's reader is partly C (Cython) and some malformed files crash it with a
segmentation fault (scipy 1.17: a 531-byte mutated v5 file, kept as a test). A
reader of user files must not take the interpreter down, so `load_variables`
runs `scipy.io.loadmat` in a forked child (`dampnet.data.child`, shared with the lab-file
readers): a crash, a hang or an exception in the child is a DataError in the parent.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from dampnet.data.child import run_isolated


class NonNumeric:
    """A variable that is not a numeric array (struct, cell, text): its description only."""

    def __init__(self, dtype: str):
        self.dtype = dtype


def _loadmat(path: str) -> dict:
    from scipy.io import loadmat

    with warnings.catch_warnings():
        # "returned data may be corrupt" (VAX/Cray byte orders) and the like: refused, not loaded
        warnings.simplefilter("error")
        m = loadmat(path)
    return {k: v for k, v in m.items() if not k.startswith("__")}


def _split(m: dict) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Numeric arrays, and the dtype description of everything else."""
    numeric, other = {}, {}
    for k, v in m.items():
        a = np.asarray(v)
        if np.issubdtype(a.dtype, np.number):
            numeric[k] = a
        else:
            other[k] = str(a.dtype)
    return numeric, other


def _read(path: str) -> tuple[dict[str, np.ndarray], dict]:
    """In the child (dampnet.data.child): the numeric arrays, and the other variables' dtypes."""
    numeric, other = _split(_loadmat(path))
    return numeric, {"other": other}


def load_variables(path: Path) -> dict[str, np.ndarray | NonNumeric]:
    """The variables of a .mat file (name -> array, or NonNumeric); DataError if unreadable."""
    import scipy.io  # noqa: F401  (imported once here, not in every child)

    numeric, head = run_isolated(_read, path, f"{path}: not a readable MATLAB v4-v7.2 .mat file",
                                 "the MATLAB reader (scipy)")
    out: dict[str, np.ndarray | NonNumeric] = dict(numeric)
    out.update({k: NonNumeric(d) for k, d in head["other"].items()})
    return out
