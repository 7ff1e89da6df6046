"""Dyno data: the dataset format, readers for real measurements, preprocessing, the virtual rig.

  types.py       DynoTest, Dataset, DataError, channel names and SI units
  units.py       unit-bearing column names -> channel and SI conversion
  table.py       numeric text tables with cell-level error messages
  validate.py    checks on a loaded test (time, NaN, samples)
  fileformat.py  the dataset directory (manifest.csv + one CSV per test): read, write
  testbuild.py   build_test: SI channel arrays -> a checked DynoTest (control, signs, time)
  readers.py     load_dataset: directories, single CSV/text files, .mat files, lab files
  child.py       a file-format library's reader run in a child process (crash-safe)
  excitation.py  a sine's frequency and amplitude estimated from the displacement (or not a sine)
  lab/           TDMS, MDF 3/4, RPC III through their own libraries, with a channel map
  real.py        the two real MR-damper data sets in ../shared/data
  preprocess.py  acceleration, decimation, hold-out and by-test splits
  merge.py       several datasets as one (merge_datasets)
  runorder.py    the run order a dataset states (manifest run_order / started), or none
  artefacts.py   measurement artefacts (a late force channel, a drift, slips, offsets) and their
                 data fixes; dampnet.diagnosis.artefacts tests for them
  rig/           the virtual shock dyno (generate, EFFECTS, truth_force, TruthDamper)
"""

from dampnet.data.fileformat import write_dataset
from dampnet.data.merge import merge_datasets
from dampnet.data.preprocess import (THESIS_WINDOW_S, add_acceleration, decimate, holdout_split,
                                     split_by_tests)
from dampnet.data.readers import load_dataset, read_mat, read_text, takes_channel_map
from dampnet.data.types import DataError, Dataset, DynoTest

__all__ = ["DataError", "Dataset", "DynoTest", "load_dataset", "read_mat", "read_text", "takes_channel_map",
           "write_dataset", "add_acceleration", "decimate", "holdout_split", "split_by_tests",
           "THESIS_WINDOW_S"]
