"""Suite-wide settings, applied before any test module imports numpy.

One OpenBLAS thread: the suite runs serially on small matrices, where a second BLAS thread only
spins, and on a shared 2-core machine the spinning dominates. Measured on a loaded 2-core machine:
`diagnose` of a 6-test rig dataset took 24.6 s CPU (69 s wall) with 2 threads and 3.65 s CPU
(12 s wall) with 1. Commands the tests start in subprocesses inherit it. An explicit setting
in the environment wins.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
