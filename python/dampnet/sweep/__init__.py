"""Sweeps over training, quarter-car and full-vehicle simulation settings on Dask (`dampnet sweep SPEC.toml`).

    import dampnet.sweep
    df = dampnet.sweep.run("sweep.toml", out="sweep-out")    # a pandas DataFrame, one row per cell

One job per module, each importing only the ones above it:

  metrics.py     the metrics a cell reports (the table's columns, the possible objectives)
  spec.py        SPEC.toml: its tables and keys, read and checked (SpecError: one line, file, line, field)
  grid.py        the spec's cells: grid x random samples, parameters that do not apply dropped
  hashing.py     content hashes of input files, dampnet's source hash, each cell's key
  inputs.py      a cell's inputs (datasets, models, road files): by path (shared filesystem) or shipped
  train_cell.py  one training cell (on a worker): train_dataset, model_metrics
  sim_cell.py    one simulation cell (on a worker): dampnet.sim.quarter_car.runs.simulate and its ride metrics
  fullcar_cell.py  one full-vehicle cell (on a worker): dampnet.sim.full_car.runs.run and its test's metrics
  tasks.py       what a worker runs: one cell, its error recorded, its time measured
  store.py       the sweep directory: state, each cell saved atomically as it completes, model directories
  table.py       the results table (pandas; Parquet, CSV)
  summary.py     the best cells and the sensitivities (summary.json, summary.txt)
  plots.py       the sensitivity plots (PNG)
  progress.py    the progress bar with the time left (stderr)
  runner.py      the cluster (embedded LocalCluster, a scheduler's address or file), the workers'
                 dampnet checked, submission, faults (a lost scheduler, no worker), run()

Needs the `sweep` extra: dask[distributed], pandas, pyarrow.
"""

from __future__ import annotations

from dampnet.sweep.runner import SweepError, SweepInterrupted, run
from dampnet.sweep.spec import SpecError, load_spec, parse_spec

__all__ = ["run", "load_spec", "parse_spec", "SpecError", "SweepError", "SweepInterrupted"]
