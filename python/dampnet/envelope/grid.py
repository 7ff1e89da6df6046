"""The runtime's coarse training envelope: what an FMU, a HIL loop or a controller can check each
step in bounded time (dampnet.h, "Training envelope"; the C++ check is dampnet::Envelope).

From a model's envelope (dampnet.envelope: its stored training samples), for every pair of
inputs (i < j) a DN_ENVELOPE_CELLS x DN_ENVELOPE_CELLS bitmap over the two inputs' training
ranges marks the cells a training sample fell in and, one cell each way, the cells around them
(DILATE_CELLS): a run that follows the data, or passes between two samples of one sine test, stays
in marked cells; a run between two training control levels (2 scaled units apart on the quick
plan), or off the sine tests' (velocity, acceleration) ellipses by more than a cell or two, does
not. A cell is 2/32 = 0.0625 scaled units wide (1 scaled unit = half an input's training range),
so the flag is coarser than the k-d tree measure and sees only 2-D shadows: `coverage` reports
both, and how often they agree, for every run.

  cells = grid_cells(env)               # uint32 [n_pairs, DN_ENVELOPE_PAIR_WORDS]
  rt = runtime_envelope(env)            # dampnet._core.Envelope: rt.check(X) -> flags [n]
  flags = runtime_flags(env, X)         # the same, in one call (X [n, n_inputs], feature units)
"""

from __future__ import annotations

import numpy as np

from dampnet.envelope.samples import Envelope

#: cells a training sample marks around its own in each direction (1: a 3 x 3 block)
DILATE_CELLS = 1


def _constants() -> tuple[int, int]:
    from dampnet import _core

    return int(_core.ENVELOPE_CELLS), int(_core.ENVELOPE_PAIR_WORDS)


def grid_size() -> int:
    """Cells per input across its training range (DN_ENVELOPE_CELLS)."""
    return _constants()[0]


def pairs(n_inputs: int) -> list[tuple[int, int]]:
    """The input pairs (i < j) in the bitmaps' order: (0,1), (0,2), .., (1,2), .."""
    return [(i, j) for i in range(n_inputs) for j in range(i + 1, n_inputs)]


def cell_index(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, cells: int) -> np.ndarray:
    """The cell [n, n_inputs] of each input of x [n, n_inputs] (feature units), as the C++ check
    computes it (dampnet.h): floor((x - lo) * (cells / (hi - lo))), the last cell for x = hi, one
    cell (0) for a constant input (hi = lo); -1 outside [lo, hi] or NaN."""
    x = np.asarray(x, dtype=np.float64)
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi >= lo)
            and np.all(np.isfinite(hi - lo))):
        raise ValueError(f"envelope ranges: expected finite lo <= hi with a finite width, got lo {lo}, hi {hi}")
    with np.errstate(divide="ignore"):
        scale = float(cells) / (hi - lo)
    scale = np.where((hi > lo) & np.isfinite(scale), scale, 0.0)
    inside = (x >= lo) & (x <= hi)
    c = np.zeros(x.shape, dtype=np.int64)
    c[inside] = np.floor((np.where(inside, x, lo) - lo) * scale)[inside]
    c = np.minimum(c, cells - 1)
    c[~inside] = -1
    return c


def grid_cells(env: Envelope, dilate: int = DILATE_CELLS) -> np.ndarray:
    """The per-pair occupancy bitmaps [n_pairs, DN_ENVELOPE_PAIR_WORDS] (uint32) of env's stored
    training samples, each sample's cell and `dilate` cells around it marked."""
    cells, words = _constants()
    n = len(env.features)
    # back to feature units (clipped: a training sample is in its range, whatever the rounding)
    x = np.clip((env.points - env.in_ymin) / env.in_gain + env.in_offset, env.lo, env.hi)
    ci = cell_index(x, env.lo, env.hi, cells)
    ci = ci[np.all(ci >= 0, axis=1)]
    from scipy.ndimage import binary_dilation

    square = np.ones((2 * dilate + 1, 2 * dilate + 1), dtype=bool)
    out = np.zeros((len(pairs(n)), words), dtype=np.uint32)
    for p, (i, j) in enumerate(pairs(n)):
        occupied = np.zeros((cells, cells), dtype=bool)
        occupied[ci[:, i], ci[:, j]] = True
        grown = binary_dilation(occupied, structure=square) if dilate else occupied
        # bit ci * cells + cj: little-endian bit order within bytes, bytes within words
        out[p] = np.packbits(grown.ravel(), bitorder="little").view("<u4")
    return out


def runtime_envelope(env: Envelope):
    """The C++ check of env's grid (dampnet._core.Envelope), built once per envelope."""
    from dampnet import _core

    if env._runtime is None:
        env._runtime = _core.Envelope(env.lo, env.hi, grid_cells(env))
    return env._runtime


def ranges_check(lo: np.ndarray, hi: np.ndarray):
    """The C++ check of the training ranges alone, every cell marked: what an FMU exported without
    its envelope computes (dampnet::Envelope::load_ranges)."""
    from dampnet import _core

    n = len(lo)
    return _core.Envelope(lo, hi, np.full((n * (n - 1) // 2, _constants()[1]), 0xFFFFFFFF, dtype=np.uint32))


def runtime_flags(env: Envelope, X: np.ndarray) -> np.ndarray:
    """What the runtime's check says of inputs X [n, n_inputs] (feature units): flags [n] (uint32;
    0 inside, bit 0 outside a range or NaN, bit 1 outside the grid)."""
    return runtime_envelope(env).check(np.asarray(X, dtype=np.float64))
