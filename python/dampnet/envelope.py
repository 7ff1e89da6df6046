"""A model's training envelope: where its training data were, so a run can tell where it guesses.

Two parts, both built from the samples the model was fitted on (`build_envelope`):

  ranges  the per-input training range [lo, hi] in feature units: the model's saturation
          limits sat_lo / sat_hi (dampnet.training.fit sets them to the training range), so
          even a model without an envelope file has them;
  joint   the distance from a point to the nearest training sample in the model's scaled
          input space (its own mapminmax: s = (x - in_offset) in_gain + in_ymin, every
          training input in [-1, 1], so one unit there is half an input's training range).
          A point inside every range can still be far from any training sample (the thesis's
          sines at 0.25-3 Hz fill an ellipse in (velocity, acceleration), not the box around
          it; the controls are a few levels, not a continuum).

The joint measure is a k-d tree (scipy.spatial.cKDTree, off the real-time path) over at most
MAX_POINTS training samples (a random subsample, seeded, when there are more). Its threshold
comes from the data themselves:

  threshold = THRESHOLD_FACTOR x the NN_PERCENTILE-th percentile of the stored points'
              distances to their nearest other stored point.

Why: on a sine test the samples are a curve, and the nearest-neighbour distance of a stored
point is the spacing of the stored curve where it is sparsest (the fast middle of a stroke,
in acceleration; or where two tests cross). A trajectory that follows the training data is
within half that spacing of a stored point; the 99th percentile ignores the few isolated
points (zero-force points, a test's ends) and THRESHOLD_FACTOR = 3 accepts points up to
three sparse spacings away from the data (interpolation across a gap that the data
themselves have) but not across a hole: on the quick plan (0.25, 1, 3 Hz x 0 and 5 V) the
threshold is a few hundredths of the scaled range (printed by `describe`), while the gap between
the 0 V and 5 V tests is 2 scaled units and the quarter-car impulse goes several units beyond
the range. A run between two training control levels is therefore outside the joint envelope
(the model interpolates there; the held-out level measures how well). This is a coverage
statement, not an error estimate.

Files beside the model (`save_envelope`, `load_envelope`; written into the model directory by
`dampnet.modeldir.save_model_dir(..., envelope=...)`): ENVELOPE_NPZ (the stored points,
scaled, and the ranges) and ENVELOPE_JSON (the parameters: schema, the model's id, features,
units, ranges, threshold and how it was derived, counts).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dampnet.outputs import atomic_write_bytes, atomic_write_text, json_text

SCHEMA = "dampnet.envelope/1"
ENVELOPE_NPZ = "envelope.npz"
ENVELOPE_JSON = "envelope.json"
#: most training samples the k-d tree holds (a seeded random subsample beyond)
MAX_POINTS = 20000
#: the percentile of the stored points' nearest-neighbour distances the threshold starts from
NN_PERCENTILE = 99.0
#: the threshold is this many times that percentile (see the module docstring)
THRESHOLD_FACTOR = 3.0


@dataclass
class Envelope:
    """A model's training envelope. Arrays in feature units except `points` (scaled, [-1, 1])."""

    features: list[str]
    units: list[str]
    lo: np.ndarray  # [n_in] training range, feature units
    hi: np.ndarray
    in_offset: np.ndarray  # the model's mapminmax, to scale run inputs as the stored points
    in_gain: np.ndarray
    in_ymin: float
    points: np.ndarray  # [m, n_in] stored training samples, scaled
    threshold: float  # joint distance beyond which a point is outside [scaled units]
    params: dict[str, Any] = field(default_factory=dict)
    _tree: Any = field(default=None, repr=False, compare=False)
    _runtime: Any = field(default=None, repr=False, compare=False)  # dampnet.envelope_grid's check, built once

    def scale(self, x: np.ndarray) -> np.ndarray:
        """Inputs [n, n_in] in feature units -> the model's scaled space."""
        x = np.asarray(x, dtype=np.float64)
        return (x - self.in_offset) * self.in_gain + self.in_ymin

    @property
    def tree(self):
        if self._tree is None:
            from scipy.spatial import cKDTree

            self._tree = cKDTree(self.points)
        return self._tree

    def nearest(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distance [n] in scaled units, index [n] of the nearest stored point) of inputs x [n, n_in]
        (feature units). Non-finite rows get distance inf and index -1."""
        s = np.atleast_2d(self.scale(x))
        d = np.full(s.shape[0], np.inf)
        idx = np.full(s.shape[0], -1, dtype=np.int64)
        ok = np.all(np.isfinite(s), axis=1)
        if ok.any():
            dd, ii = self.tree.query(s[ok], k=1)
            d[ok], idx[ok] = dd, ii
        return d, idx

    def distance(self, x: np.ndarray) -> np.ndarray:
        """Distance [n] (scaled units) of inputs x [n, n_in] (feature units) to the nearest stored point."""
        return self.nearest(x)[0]

    def describe(self) -> str:
        p = self.params
        return (f"joint envelope: {self.points.shape[0]} of {p.get('n_training', '?')} training samples, threshold "
                f"{self.threshold:.4g} (scaled units: 1 = half an input's training range) = {p.get('factor')} x the "
                f"{p.get('percentile'):g}th percentile {p.get('nn_percentile_value', float('nan')):.4g} of their "
                "nearest-neighbour distances")


def check_belongs(env: Envelope, model) -> None:
    """ValueError unless `env` is `model`'s envelope: the same features, and built for its id."""
    if list(env.features) != list(model.features):
        raise ValueError(f"envelope: features {env.features} are not the model's {model.features}")
    if env.params.get("model_id") not in (None, model.model_id()):
        raise ValueError(f"envelope: built for model {env.params.get('model_id')}, not {model.model_id()}")


def _nn_distances(points: np.ndarray) -> np.ndarray:
    """Each point's distance to its nearest other point (duplicates count: distance 0)."""
    from scipy.spatial import cKDTree

    if points.shape[0] < 2:
        return np.zeros(points.shape[0])
    d, _ = cKDTree(points).query(points, k=2)
    return d[:, 1]


def build_envelope(model, X: np.ndarray, max_points: int = MAX_POINTS, seed: int = 0,
                   percentile: float = NN_PERCENTILE, factor: float = THRESHOLD_FACTOR) -> Envelope:
    """The envelope of `model` from its training samples X [n, n_inputs] (feature units, the
    model's features in order: dampnet.training.pipeline.Prepared.X, or `training_samples`)."""
    X = np.asarray(X, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] != model.n_inputs:
        raise ValueError(f"training samples: expected [n, {model.n_inputs}] ({', '.join(model.features)}), "
                         f"got shape {X.shape}")
    X = X[np.all(np.isfinite(X), axis=1)]
    if X.shape[0] == 0:
        raise ValueError("training samples: none finite")
    n = X.shape[0]
    if n > max_points:
        rows = np.sort(np.random.default_rng(seed).choice(n, size=max_points, replace=False))
        X = X[rows]
    scaled = (X - model.in_offset) * model.in_gain + model.in_ymin
    nn = _nn_distances(scaled)
    p_val = float(np.percentile(nn, percentile)) if nn.size else 0.0
    threshold = factor * p_val
    if not threshold > 0:  # a single point or duplicates only: no spread to measure
        threshold = 1e-9
    params = dict(n_training=int(n), n_points=int(X.shape[0]), max_points=int(max_points), seed=int(seed),
                  percentile=float(percentile), factor=float(factor), nn_percentile_value=p_val,
                  nn_median=float(np.median(nn)) if nn.size else 0.0, model_id=model.model_id())
    return Envelope(list(model.features), list(model.units), model.sat_lo.copy(), model.sat_hi.copy(),
                    model.in_offset.copy(), model.in_gain.copy(), float(model.in_ymin), scaled,
                    float(threshold), params)


def training_samples(model, split) -> np.ndarray:
    """The samples the model was fitted on, rebuilt from a training Split
    (dampnet.training.pipeline.train_dataset's third result): the model's features at the full
    sample rate of split.train's tests, then every split.decimate-th row, as
    pipeline.prepare_training builds Prepared.X."""
    from dampnet.features import feature_matrix

    window = (model.meta.get("data") or {}).get("acceleration_window_s")
    return np.concatenate([feature_matrix([t], model.features, model.feature_params, window)[::split.decimate]
                           for t in split.train.tests])


def envelope_of(model, split, **kw) -> Envelope:
    """`build_envelope(model, training_samples(model, split))`: the hook for `dampnet train` and
    the demo (save_model_dir(model, metrics, out, envelope=envelope_of(model, split)))."""
    return build_envelope(model, training_samples(model, split), **kw)


# -- files ------------------------------------------------------------------------------------

def _params_json(env: Envelope) -> dict[str, Any]:
    return dict(schema=SCHEMA, features=env.features, units=env.units, lo=env.lo, hi=env.hi,
                threshold=env.threshold, threshold_unit="scaled input space (mapminmax [-1, 1]: 1 = half an "
                "input's training range)", **env.params)


def save_envelope(env: Envelope, model_dir: str | os.PathLike) -> list[Path]:
    """Write ENVELOPE_NPZ and ENVELOPE_JSON into model_dir, each atomically (temporary file and
    rename; inside save_model_dir's staging directory the whole model directory is atomic)."""
    d = Path(model_dir)
    d.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(d / ENVELOPE_NPZ, lambda f: np.savez_compressed(
        f, points=env.points, lo=env.lo, hi=env.hi, in_offset=env.in_offset, in_gain=env.in_gain,
        in_ymin=np.array(env.in_ymin), threshold=np.array(env.threshold)), overwrite=True)
    atomic_write_text(d / ENVELOPE_JSON, json_text(_params_json(env)), overwrite=True)
    return [d / ENVELOPE_NPZ, d / ENVELOPE_JSON]


def envelope_dir(model_path: str | os.PathLike) -> Path:
    """The directory an envelope of the model at model_path (a directory or its model.json) lives in."""
    p = Path(model_path)
    return p if p.is_dir() else p.parent


def load_envelope(model_path: str | os.PathLike, model=None) -> tuple[Envelope | None, str]:
    """(the envelope beside a model, a note): (None, why) when there is none, it is unreadable,
    or it belongs to another model (its model id differs from `model`'s)."""
    d = envelope_dir(model_path)
    npz, js = d / ENVELOPE_NPZ, d / ENVELOPE_JSON
    if not npz.is_file() or not js.is_file():
        return None, f"no {ENVELOPE_NPZ} beside the model: per-input training ranges only"
    try:
        meta = json.loads(js.read_text(encoding="utf-8"))
        with np.load(npz) as z:
            arr = {k: z[k] for k in z.files}
        if meta.get("schema") != SCHEMA:
            return None, f"{js}: schema {meta.get('schema')!r} is not {SCHEMA}: per-input training ranges only"
        params = {k: v for k, v in meta.items()
                  if k not in ("schema", "features", "units", "lo", "hi", "threshold", "threshold_unit")}
        env = Envelope(list(meta["features"]), list(meta["units"]), arr["lo"], arr["hi"], arr["in_offset"],
                       arr["in_gain"], float(arr["in_ymin"]), arr["points"], float(arr["threshold"]), params)
    except (OSError, ValueError, KeyError, TypeError) as e:
        return None, f"{npz}: unreadable ({e}): per-input training ranges only"
    if env.points.ndim != 2 or env.points.shape[1] != len(env.features):
        return None, f"{npz}: points of shape {env.points.shape} do not match its features: per-input ranges only"
    if model is not None and params.get("model_id") not in (None, model.model_id()):
        return None, (f"{js} belongs to model {params.get('model_id')}, not {model.model_id()}: "
                      "per-input training ranges only")
    return env, "joint envelope " + str(npz)
