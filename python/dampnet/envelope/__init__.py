"""A model's training envelope: where its training data were, and how far a run leaves them.

  samples.py   the envelope itself (Envelope: the per-input ranges and the joint k-d tree over
               the training samples), built from a model's training split, its files beside the
               model (envelope.npz, envelope.json) and their checks
  grid.py      the runtime's bounded-time form of the joint envelope (an occupancy grid per input
               pair, what the C++ runtime, the header and the FMU check)
  coverage.py  a run's coverage: the share of its time outside the ranges and the joint envelope,
               the verdict, and the model inputs of a quarter-car or full-car run
  plot.py      coverage plots (a run's inputs over the training samples, per input pair)

`from dampnet.envelope import X` gives samples.py's names; the others by their module.
"""

from dampnet.envelope.samples import (ENVELOPE_JSON, ENVELOPE_NPZ, MAX_NPZ_BYTES, MAX_POINTS, NN_PERCENTILE,
                                      NPZ_ARRAYS, SCHEMA, THRESHOLD_FACTOR, Envelope, EnvelopeError,
                                      build_envelope, check_belongs, envelope_dir, envelope_files, envelope_of,
                                      load_envelope, read_envelope, save_envelope, training_samples,
                                      validate_envelope)

__all__ = ["ENVELOPE_JSON", "ENVELOPE_NPZ", "MAX_NPZ_BYTES", "MAX_POINTS", "NN_PERCENTILE", "NPZ_ARRAYS", "SCHEMA",
           "THRESHOLD_FACTOR", "Envelope", "EnvelopeError", "build_envelope", "check_belongs", "envelope_dir",
           "envelope_files", "envelope_of", "load_envelope", "read_envelope", "save_envelope", "training_samples",
           "validate_envelope"]
