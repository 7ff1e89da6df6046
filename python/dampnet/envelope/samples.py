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
points (rest points, a test's ends) and THRESHOLD_FACTOR = 3 accepts points up to
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

An envelope is checked like a model, however it is made (`validate_envelope`, run by Envelope()
itself): from files by `read_envelope` (EnvelopeError, one line naming the file and the field:
what `dampnet export` uses) or `load_envelope` (the coverage commands: a damaged envelope is
ignored with a one-line warning and the per-input ranges are used, as for a model without one).
"""

from __future__ import annotations

import os
import struct
import sys
import zipfile
import zlib
from dataclasses import InitVar, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dampnet import _core, schema
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
#: most bytes the arrays of an envelope.npz may expand to: 1 million stored points of 8 inputs
#: (50 x MAX_POINTS), checked before anything is decompressed (a small file can expand to gigabytes)
MAX_NPZ_BYTES = 64 * 2**20
#: the arrays of ENVELOPE_NPZ
NPZ_ARRAYS = ("points", "lo", "hi", "in_offset", "in_gain", "in_ymin", "threshold")


class EnvelopeError(ValueError):
    """An envelope (its files or fields) that is not a usable training envelope: one line naming
    the file and the field."""


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
    _runtime: Any = field(default=None, repr=False, compare=False)  # dampnet.envelope.grid's check, built once
    #: where the arrays and the parameters came from, for messages: a name, or (npz, json) file names
    source: InitVar[Any] = None

    def __post_init__(self, source) -> None:
        validate_envelope(self, source)

    def scale(self, x: np.ndarray) -> np.ndarray:
        """Inputs [n, n_in] in feature units -> the model's scaled space."""
        x = np.asarray(x, dtype=np.float64)
        with np.errstate(over="ignore", invalid="ignore"):  # a non-finite result is a point outside
            return (x - self.in_offset) * self.in_gain + self.in_ymin

    @property
    def tree(self):
        if self._tree is None:
            from scipy.spatial import cKDTree

            # 64 points a leaf, not scipy's 16: the exact nearest sample of a step far outside the
            # data (most steps of a run that leaves it) about a fifth faster. The same distances
            # (each one the same arithmetic on the same pair) and, but for exact ties between two
            # distinct samples, the same indices: so on the demo's 52 largest queries
            self._tree = cKDTree(self.points, leafsize=64)
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

    def far(self, x: np.ndarray) -> np.ndarray:
        """Whether each input x [n, n_in] (feature units) is farther than the threshold from every
        stored point (non-finite rows: True): `nearest(x)[0] > threshold`, found faster (the tree
        stops looking beyond the threshold)."""
        s = np.atleast_2d(self.scale(x))
        out = np.ones(s.shape[0], dtype=bool)
        ok = np.all(np.isfinite(s), axis=1)
        if ok.any():   # a neighbour at exactly the threshold is within it, as in nearest's test
            dd, _ = self.tree.query(s[ok], k=1, distance_upper_bound=np.nextafter(self.threshold, np.inf))
            out[ok] = ~(dd <= self.threshold)
        return out

    def distance(self, x: np.ndarray) -> np.ndarray:
        """Distance [n] (scaled units) of inputs x [n, n_in] (feature units) to the nearest stored point."""
        return self.nearest(x)[0]

    def describe(self) -> str:
        p = self.params

        def num(key: str) -> str:  # the file's informative numbers, whatever they hold
            v = p.get(key)
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                return "?"
            return str(v) if isinstance(v, int) else f"{v:.4g}"

        return (f"joint envelope: {self.points.shape[0]} of {num('n_training')} training samples, threshold "
                f"{self.threshold:.4g} (scaled units: 1 = half an input's training range) = {num('factor')} x the "
                f"{num('percentile')}th percentile {num('nn_percentile_value')} of their "
                "nearest-neighbour distances")


def _sources(source) -> tuple[str, str]:
    """(where the arrays came from, where the parameters came from) for messages."""
    if isinstance(source, tuple):
        return str(source[0]), str(source[1])
    return (str(source), str(source)) if source is not None else ("envelope", "envelope")


def _float_array(value: Any, where: str) -> np.ndarray:
    """value as float64: real numbers only (not text, objects or complex numbers)."""
    a = np.asarray(value) if isinstance(value, np.ndarray) else None
    if a is not None and a.dtype.kind not in "biuf":
        raise EnvelopeError(f"{where}: expected real numbers, got an array of {a.dtype.name}")
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise EnvelopeError(f"{where}: expected real numbers, got {schema.show(value)}") from None


def _scalar(value: Any, where: str) -> float:
    a = _float_array(value, where)
    if a.shape not in ((), (1,)):
        raise EnvelopeError(f"{where}: expected one number, got an array of shape {a.shape}")
    return float(a.reshape(()))


def validate_envelope(env: Envelope, source: Any = None) -> Envelope:
    """`env` with its arrays as float64 if it is a usable envelope; EnvelopeError naming the file
    (`source`: a name, or (npz, json) file names) and the field otherwise. The one check of an
    envelope, however it was made (Envelope() runs it; so do read_envelope and build_envelope):

      features, units  1..DN_MAX_INPUTS distinct names, one unit each
      lo, hi           one finite number per input, lo <= hi, a finite width (the training ranges)
      in_offset        one finite number per input; in_gain: finite, non-zero, with a finite
                       inverse (the model's mapminmax, used both ways); in_ymin finite
      points           [m >= 1, n_inputs] finite, and finite back in feature units
      threshold        a finite number > 0 (scaled units)

    Without this a NaN or negative threshold, an in_gain of 0 or no stored points gave silently
    wrong coverage (0 % or 100 % outside), an IndexError, or a runtime grid flagging every step."""
    npz, js = _sources(source)

    def bad(where: str, what: str) -> EnvelopeError:
        return EnvelopeError(f"{where}: {what}")

    feats, units = env.features, env.units
    if not isinstance(feats, (list, tuple)) or not all(isinstance(f, str) and f for f in feats):
        raise bad(f"{js}: features", f"expected a list of input names, got {schema.show(feats)}")
    if not 1 <= len(feats) <= _core.MAX_INPUTS or len(set(feats)) != len(feats):
        raise bad(f"{js}: features", f"expected 1 to {_core.MAX_INPUTS} distinct input names, got "
                  f"{schema.show(', '.join(feats))}")
    if not isinstance(units, (list, tuple)) or not all(isinstance(u, str) for u in units) or len(units) != len(feats):
        raise bad(f"{js}: units", f"expected {len(feats)} unit names (one per feature), got {schema.show(units)}")
    env.features, env.units = list(feats), list(units)
    n = len(feats)
    for name in ("lo", "hi", "in_offset", "in_gain"):
        a = _float_array(getattr(env, name), f"{npz}: {name}")
        if a.shape != (n,):
            raise bad(f"{npz}: {name}", f"expected {n} values (one per feature: {', '.join(feats)}), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            i = int(np.argmin(np.isfinite(a)))
            raise bad(f"{npz}: {name}", f"expected finite numbers, got {schema.show(float(a[i]))} for {feats[i]}")
        setattr(env, name, a)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        width = env.hi - env.lo
        inverse = 1.0 / env.in_gain
    for i in range(n):
        if not (env.lo[i] <= env.hi[i] and np.isfinite(width[i])):
            raise bad(f"{npz}: lo, hi", f"expected lo <= hi with a finite width, got [{env.lo[i]:.6g}, "
                      f"{env.hi[i]:.6g}] for {feats[i]}")
        if env.in_gain[i] == 0 or not np.isfinite(inverse[i]):
            raise bad(f"{npz}: in_gain", f"expected a non-zero gain with a finite inverse (the model's mapminmax "
                      f"scaling), got {env.in_gain[i]:.6g} for {feats[i]}")
    env.in_ymin = _scalar(env.in_ymin, f"{npz}: in_ymin")
    if not np.isfinite(env.in_ymin):
        raise bad(f"{npz}: in_ymin", f"expected a finite number, got {env.in_ymin}")
    pts = _float_array(env.points, f"{npz}: points")
    if pts.ndim != 2 or pts.shape[1] != n or pts.shape[0] < 1:
        raise bad(f"{npz}: points", f"expected [m >= 1 stored samples, {n} inputs], got shape {pts.shape}")
    with np.errstate(over="ignore", invalid="ignore"):
        back = (pts - env.in_ymin) * inverse + env.in_offset
    if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(back))):
        row = int(np.argmin(np.all(np.isfinite(pts) & np.isfinite(back), axis=1)))
        raise bad(f"{npz}: points", f"expected finite scaled samples, got [{', '.join(f'{v:.6g}' for v in pts[row])}] "
                  f"in row {row}")
    env.points = pts
    env.threshold = _scalar(env.threshold, f"{npz}: threshold")
    if not (np.isfinite(env.threshold) and env.threshold > 0):
        raise bad(f"{npz}: threshold", f"expected a finite distance > 0 (scaled units), got {env.threshold}")
    if not isinstance(env.params, dict):
        raise bad(js, f"expected a JSON object of parameters, got {schema.show(env.params)}")
    mid = env.params.get("model_id")
    if mid is not None and not isinstance(mid, str):
        raise bad(f"{js}: model_id", f"expected the model's id (a string), got {schema.show(mid)}")
    return env


def check_belongs(env: Envelope, model, source: Any = None) -> None:
    """EnvelopeError unless `env` is `model`'s envelope: the same features, built for its id,
    and the model's ranges and input scaling (what the envelope measures with)."""
    npz, js = _sources(source)
    if list(env.features) != list(model.features):
        raise EnvelopeError(f"{js}: features {env.features} are not the model's {model.features}")
    if env.params.get("model_id") not in (None, model.model_id()):
        raise EnvelopeError(f"{js}: built for model {env.params.get('model_id')}, not {model.model_id()}")
    for name, mine in (("lo", model.sat_lo), ("hi", model.sat_hi), ("in_offset", model.in_offset),
                       ("in_gain", model.in_gain), ("in_ymin", model.in_ymin)):
        if not np.array_equal(getattr(env, name), mine):
            what = {"lo": "sat_lo", "hi": "sat_hi"}.get(name, name)
            raise EnvelopeError(f"{npz}: {name}: differs from the model's {what}: not this model's envelope")


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


def envelope_files(model_path: str | os.PathLike) -> list[Path]:
    """[ENVELOPE_NPZ, ENVELOPE_JSON] beside the model at model_path (whether they exist or not)."""
    d = envelope_dir(model_path)
    return [d / ENVELOPE_NPZ, d / ENVELOPE_JSON]


#: what numpy and zipfile raise on a damaged .npz (truncated, not a zip, bad compressed data,
#: a header that lies, pickled objects refused)
_NPZ_ERRORS = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error, struct.error,
               NotImplementedError, RuntimeError, TypeError, OverflowError)


def _read_npz(npz: Path) -> dict[str, np.ndarray]:
    """ENVELOPE_NPZ's arrays; EnvelopeError naming the file (and the array) otherwise. The
    uncompressed size is checked first (MAX_NPZ_BYTES), no pickled objects are loaded."""
    try:
        with zipfile.ZipFile(npz) as zf:
            size = sum(i.file_size for i in zf.infolist())
        if size > MAX_NPZ_BYTES:
            raise EnvelopeError(f"{npz}: expands to {size} bytes, more than the {MAX_NPZ_BYTES} an envelope "
                                "may hold")
        with np.load(npz, allow_pickle=False) as z:
            names = set(z.files)
            out = {}
            for name in NPZ_ARRAYS:
                if name not in names:
                    raise EnvelopeError(f"{npz}: {name}: missing (an envelope holds {', '.join(NPZ_ARRAYS)})")
                try:
                    out[name] = z[name]
                except _NPZ_ERRORS as e:
                    raise EnvelopeError(f"{npz}: {name}: unreadable ({schema.show(str(e) or type(e).__name__)})"
                                        ) from None
        return out
    except _NPZ_ERRORS as e:  # EnvelopeError is a ValueError: re-raised as it is
        if isinstance(e, EnvelopeError):
            raise
        raise EnvelopeError(f"{npz}: not a readable envelope file ({type(e).__name__}: "
                            f"{schema.show(str(e), 120)})") from None


def read_envelope(model_path: str | os.PathLike, model=None) -> Envelope | None:
    """The envelope beside a model (a directory or its model.json), validated
    (validate_envelope; with `model`, check_belongs too); None when neither ENVELOPE_NPZ nor
    ENVELOPE_JSON is there. EnvelopeError (one line: the file and the field) when one of the two
    is missing, a file is unreadable, a field is out of range, or it is another model's."""
    npz, js = envelope_files(model_path)
    have = [p for p in (npz, js) if p.exists()]
    if not have:
        return None
    if len(have) == 1:
        other = js if have[0] == npz else npz
        raise EnvelopeError(f"{other}: missing (its companion {have[0].name} is there; an envelope is both files)")
    meta = schema.expect_object(schema.load_json(js, EnvelopeError), str(js), EnvelopeError)
    if meta.get("schema") != SCHEMA:
        raise EnvelopeError(f"{js}: schema: expected {SCHEMA!r}, got {schema.show(meta.get('schema'))}")
    for key in ("features", "units"):
        schema.expect_strings(meta.get(key), f"{js}: {key}", EnvelopeError)
    arr = _read_npz(npz)
    params = {k: v for k, v in meta.items()
              if k not in ("schema", "features", "units", "lo", "hi", "threshold", "threshold_unit")}
    env = Envelope(meta["features"], meta["units"], arr["lo"], arr["hi"], arr["in_offset"], arr["in_gain"],
                   arr["in_ymin"], arr["points"], arr["threshold"], params, source=(npz, js))
    if model is not None:
        check_belongs(env, model, (npz, js))
    return env


def load_envelope(model_path: str | os.PathLike, model=None) -> tuple[Envelope | None, str]:
    """(the envelope beside a model, a note) for a run's coverage: read_envelope, falling back to
    the per-input training ranges (None, why) when there is none, or, with a one-line warning on
    stderr naming the file and the field, when it is damaged or another model's (docs/coverage.md, "The
    envelope"). `dampnet export` uses read_envelope: a damaged envelope is an error there."""
    try:
        env = read_envelope(model_path, model)
    except EnvelopeError as e:
        note = f"{e}: envelope ignored, per-input training ranges only"
        print(f"dampnet: warning: {note}", file=sys.stderr)
        return None, note
    if env is None:
        return None, f"no {ENVELOPE_NPZ} beside the model: per-input training ranges only"
    return env, "joint envelope " + str(envelope_files(model_path)[0])
