"""Suite-wide settings, applied before any test module imports numpy.

One OpenBLAS thread: the suite runs serially on small matrices, where a second BLAS thread only
spins, and on a shared 2-core machine the spinning dominates. Measured on a loaded 2-core machine:
`diagnose` of a 6-test rig dataset took 24.6 s CPU (69 s wall) with 2 threads and 3.65 s CPU
(12 s wall) with 1. Commands the tests start in subprocesses inherit it. An explicit setting
in the environment wins.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# every test held to a time budget unless marked slow with a reason (tests/time_budget.py)
from time_budget import pytest_addoption, pytest_collection_modifyitems, pytest_configure  # noqa: E402,F401
