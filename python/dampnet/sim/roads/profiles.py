"""Road inputs for the quarter-car loop: impulse/bump, sine sweep, ISO 8608 classes, the thesis's rough road, CSV.

A `Road` is either *spatial* (elevation [m] against distance [m]; the time
history depends on the speed) or *temporal* (displacement [m] against time
[s]; the speed is irrelevant). `Road.sample(dt, speed)` gives the road
displacement at the loop's time step, linearly interpolated.

Inputs (thesis chapter 5, Fig. 44):

* `impulse` - temporal raised-cosine pulse z = h/2 (1 - cos(2 pi (t - t0)/d)),
  default h = 50 mm, d = 50 ms, starting at t0 = 0.5 s, 5 s long: a short,
  smooth "impulse" that excites both the wheel-hop and the body mode.
* `bump` - the same raised-cosine shape along distance (default 50 mm high,
  0.5 m long, 5 m lead-in, 40 m in all): its duration depends on the speed.
* `sine_sweep` - the bounce sine-sweep test: z = A sin(phi(t)) with an
  exponential (log) sweep from f0 = 0.5 Hz to f1 = 20 Hz,
  f(t) = f0 2^(r t), r = 0.1 octave/s by default (5.32 octaves in 53.2 s,
  slow enough that the 1 Hz body mode is met quasi-statically), constant
  displacement amplitude A = 5 mm, 1 s of rest before and 3 s after, sampled
  at 5 kHz (interpolation error below 1e-4 of A at 20 Hz).
* `iso8608` - random profiles of ISO 8608 classes A-H. Displacement PSD
  Gd(n) = Gd(n0) (n/n0)^-w, n0 = 0.1 cycle/m, waviness w = 2, Gd(n0) the
  class's geometric mean (A 16e-6 m^3 ... H 262144e-6 m^3, x4 per class).
  Synthesis: a sum of harmonics of the profile length L (n_k = k/L over the
  band [0.011, 2.83] cycle/m); harmonic k carries the exact integral of Gd
  over its bin [n_k - 1/(2L), n_k + 1/(2L)] clipped to the band (amplitude
  sqrt(2 integral), i.e. about sqrt(2 Gd(n_k)/L)), with phases uniform in
  [0, 2 pi) from `numpy.random.default_rng(seed)`, summed by an inverse FFT.
  So the displacement variance equals the integral of Gd over the band (to
  rounding), the periodogram is Gd at the bin centres (within the PSD's
  curvature over one bin), and the profile is periodic in L (it can be
  concatenated seamlessly).
  Same seed, same road.
* `thesis_rough_road` - the thesis's rough road: displacement RMS 0.016 m,
  about 184 m, "concatenated once". The thesis gives no spectrum; we use the
  ISO 8608 shape (w = 2) on a 92 m profile (so n_min = 1/92 = 0.0109 cycle/m,
  the ISO band's lower edge), scaled to RMS 0.016 m exactly (Gd(n0) =
  2.8e-4 m^3: ISO class C), and concatenated once: 184 m. Used at 10 and 20 m/s.
* `read_profile_csv` - a user's profile from a CSV with columns
  `distance_m,elevation_m` (a header row; errors name file, line and column).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field

import numpy as np


class RoadError(ValueError):
    """A nonsensical road or road request (the message says what and where)."""


#: ISO 8608 reference spatial frequency [cycle/m] and waviness.
ISO_N0 = 0.1
ISO_W = 2.0
#: ISO 8608 spatial-frequency band [cycle/m] used for synthesis.
ISO_BAND = (0.011, 2.83)
#: Geometric mean of Gd(n0) [m^3] per ISO 8608 class; class k spans [mean/2, mean*2).
ISO_CLASSES = {c: 16e-6 * 4.0 ** i for i, c in enumerate("ABCDEFGH")}


def iso_class_bounds(cls: str) -> tuple[float, float]:
    """(lower, upper) Gd(n0) [m^3] of an ISO 8608 class (A's lower bound is 0)."""
    g = ISO_CLASSES[_check_class(cls)]
    return (0.0 if cls.upper() == "A" else g / 2.0, g * 2.0)


def _check_class(cls: str) -> str:
    c = str(cls).strip().upper()
    if c not in ISO_CLASSES:
        raise RoadError(f"ISO 8608 class must be one of A-H, got {cls!r}")
    return c


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0:
        raise RoadError(f"{name} must be a positive finite number, got {value!r}")
    return v


@dataclass(frozen=True)
class RoadSample:
    """A road at the loop's time step: t [s], z [m], zdot [m/s] (central differences)."""

    t: np.ndarray
    z: np.ndarray
    zdot: np.ndarray
    speed: float | None


@dataclass
class Road:
    """A road profile: `kind` 'spatial' (x = distance [m]) or 'temporal' (x = time [s]); z = elevation [m]."""

    name: str
    kind: str
    x: np.ndarray
    z: np.ndarray
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.kind not in ("spatial", "temporal"):
            raise RoadError(f"road kind must be 'spatial' or 'temporal', got {self.kind!r}")
        self.x = np.asarray(self.x, dtype=np.float64)
        self.z = np.asarray(self.z, dtype=np.float64)
        what = "distance" if self.kind == "spatial" else "time"
        if self.x.ndim != 1 or self.x.shape != self.z.shape:
            raise RoadError(f"road {self.name!r}: {what} and elevation must be 1-D arrays of equal length")
        if self.x.size < 2:
            raise RoadError(f"road {self.name!r}: needs at least 2 points, got {self.x.size}")
        for label, arr in ((what, self.x), ("elevation", self.z)):
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise RoadError(f"road {self.name!r}: {label} is not finite at index {bad[0]} "
                                f"({arr[bad[0]]!r})")
        step = np.diff(self.x)
        if np.any(step <= 0):
            i = int(np.flatnonzero(step <= 0)[0])
            raise RoadError(f"road {self.name!r}: {what} must increase strictly "
                            f"(index {i + 1}: {self.x[i + 1]!r} after {self.x[i]!r})")

    @property
    def length(self) -> float:
        """Extent in x: metres (spatial) or seconds (temporal)."""
        return float(self.x[-1] - self.x[0])

    def duration(self, speed: float | None = None) -> float:
        """Time [s] to cover the road (spatial roads need the speed [m/s])."""
        if self.kind == "temporal":
            return self.length
        return self.length / _positive("speed [m/s]", speed)

    def sample(self, dt: float, speed: float | None = None, values_per_step: int | None = None) -> RoadSample:
        """The road displacement at t = 0, dt, ... up to the road's end (linear interpolation).
        A run of it may hold at most dampnet.sim.limits.MAX_RUN_VALUES values: steps x
        values_per_step (default a quarter-car run's); RoadError naming speed and dt beyond it."""
        from dampnet.sim import limits

        dt = _positive("time step dt [s]", dt)
        if self.kind == "spatial":
            if speed is None:
                raise RoadError(f"road {self.name!r} is a distance profile: give a speed [m/s]")
            speed = _positive("speed [m/s]", speed)
        dur = self.duration(speed)
        at = f" at {speed:.6g} m/s" if self.kind == "spatial" else ""
        try:
            limits.check_run_size(dur / dt + 1.0, values_per_step or limits.QUARTER_CAR_VALUES,
                                  f"road {self.name!r} ({dur:.6g} s{at}) in steps of dt = {dt:.6g} s",
                                  "raise the speed or the step (--speed, --dt)" if at else "raise the step (--dt)")
        except ValueError as e:
            raise RoadError(str(e)) from None
        n = int(math.floor(dur / dt + 1e-9)) + 1
        if n < 2:
            raise RoadError(f"road {self.name!r} lasts {dur:.6g} s, shorter than one time step "
                            f"({dt:.6g} s)")
        t = np.arange(n) * dt
        xq = self.x[0] + (t * speed if self.kind == "spatial" else t)
        z = np.interp(xq, self.x, self.z)
        zdot = np.gradient(z, dt)
        return RoadSample(t=t, z=z, zdot=zdot, speed=speed)

    def spacing(self) -> float:
        """Median sample spacing of x."""
        return float(np.median(np.diff(self.x)))

    def to_csv(self, path: str | os.PathLike) -> None:
        """Write `distance_m,elevation_m` (spatial roads only)."""
        if self.kind != "spatial":
            raise RoadError("only distance profiles can be written as distance_m,elevation_m")
        with open(path, "w", newline="") as f:
            f.write("distance_m,elevation_m\n")
            for a, b in zip(self.x, self.z):
                f.write(f"{a:.6f},{b:.9g}\n")


def _raised_cosine(x: np.ndarray, x0: float, width: float, height: float) -> np.ndarray:
    u = (x - x0) / width
    inside = (u >= 0) & (u <= 1)
    return np.where(inside, 0.5 * height * (1.0 - np.cos(2.0 * np.pi * np.clip(u, 0, 1))), 0.0)


def impulse(height_m: float = 0.05, duration_s: float = 0.05, start_s: float = 0.5,
            total_s: float = 5.0, fs: float = 5000.0) -> Road:
    """Temporal raised-cosine pulse (the thesis's impulse input, Fig. 44a)."""
    if not math.isfinite(height_m):
        raise RoadError(f"impulse height must be finite, got {height_m!r}")
    duration_s = _positive("impulse duration [s]", duration_s)
    total_s = _positive("total time [s]", total_s)
    fs = _positive("sample rate [Hz]", fs)
    if start_s < 0 or start_s + duration_s > total_s:
        raise RoadError("impulse must fit in [0, total_s]")
    t = np.arange(int(round(total_s * fs)) + 1) / fs
    return Road("impulse", "temporal", t, _raised_cosine(t, start_s, duration_s, height_m),
                meta=dict(input="impulse", height_m=height_m, duration_s=duration_s, start_s=start_s,
                          total_s=total_s, shape="raised cosine"))


def bump(height_m: float = 0.05, length_m: float = 0.5, lead_m: float = 5.0,
         total_m: float = 40.0, dx: float = 0.01) -> Road:
    """Spatial raised-cosine bump (duration length/speed)."""
    if not math.isfinite(height_m):
        raise RoadError(f"bump height must be finite, got {height_m!r}")
    length_m, total_m, dx = (_positive(n, v) for n, v in
                             (("bump length [m]", length_m), ("road length [m]", total_m), ("dx [m]", dx)))
    if lead_m < 0 or lead_m + length_m > total_m:
        raise RoadError("bump must fit in [0, total_m]")
    x = np.arange(int(round(total_m / dx)) + 1) * dx
    return Road("bump", "spatial", x, _raised_cosine(x, lead_m, length_m, height_m),
                meta=dict(input="bump", height_m=height_m, length_m=length_m, lead_m=lead_m,
                          shape="raised cosine"))


def sweep_frequency(t, f0: float = 0.5, f1: float = 20.0, rate_oct_s: float = 0.1) -> np.ndarray:
    """Instantaneous frequency [Hz] of the exponential sweep at time t [s] after its start."""
    return f0 * 2.0 ** (rate_oct_s * np.asarray(t, dtype=np.float64))


def sine_sweep(amplitude_m: float = 0.005, f0: float = 0.5, f1: float = 20.0,
               rate_oct_s: float = 0.1, pre_s: float = 1.0, post_s: float = 3.0,
               fs: float = 5000.0) -> Road:
    """Bounce sine sweep: A sin(phi(t)), log sweep f0 -> f1 at rate_oct_s octaves per second."""
    amplitude_m = _positive("sweep amplitude [m]", amplitude_m)
    f0, f1, rate_oct_s, fs = (_positive(n, v) for n, v in (("f0 [Hz]", f0), ("f1 [Hz]", f1),
                                                           ("sweep rate [octave/s]", rate_oct_s),
                                                           ("sample rate [Hz]", fs)))
    if f1 <= f0:
        raise RoadError(f"sweep end frequency {f1} Hz must exceed its start {f0} Hz")
    if fs < 20 * f1:
        raise RoadError(f"sample rate {fs} Hz too low for a {f1} Hz sweep (need >= {20 * f1} Hz)")
    if pre_s < 0 or post_s < 0:
        raise RoadError("rest times before and after the sweep must be >= 0")
    sweep_s = math.log2(f1 / f0) / rate_oct_s
    total = pre_s + sweep_s + post_s
    t = np.arange(int(math.floor(total * fs)) + 1) / fs
    ts = np.clip(t - pre_s, 0.0, sweep_s)
    k = rate_oct_s * math.log(2.0)
    phase = 2.0 * np.pi * f0 * np.expm1(k * ts) / k
    z = np.where((t >= pre_s) & (t <= pre_s + sweep_s), amplitude_m * np.sin(phase), 0.0)
    return Road("sine_sweep", "temporal", t, z,
                meta=dict(input="sine_sweep", amplitude_m=amplitude_m, f0_hz=f0, f1_hz=f1,
                          rate_octave_s=rate_oct_s, sweep_s=sweep_s, pre_s=pre_s, post_s=post_s,
                          law="exponential: f(t) = f0 2^(rate t)"))


def iso_psd(n, gd_n0: float, n0: float = ISO_N0, w: float = ISO_W) -> np.ndarray:
    """ISO 8608 displacement PSD Gd(n) [m^3] at spatial frequency n [cycle/m]."""
    return gd_n0 * (np.asarray(n, dtype=np.float64) / n0) ** (-w)


def iso_band_variance(gd_n0: float, band=ISO_BAND, n0: float = ISO_N0, w: float = ISO_W) -> float:
    """Integral of Gd(n) over the band [m^2] (analytic)."""
    return _psd_integral(gd_n0, band[0], band[1], n0, w)


def _psd_integral(gd_n0, a, b, n0=ISO_N0, w=ISO_W) -> float:
    if b <= a:
        return 0.0
    if abs(w - 1.0) < 1e-12:
        return gd_n0 * n0 * math.log(b / a)
    return gd_n0 * n0 ** w * (b ** (1 - w) - a ** (1 - w)) / (1 - w)


def _harmonic_profile(length_m, dx, gd_n0, band, seed, n0, w):
    length_m = _positive("road length [m]", length_m)
    dx = _positive("sample spacing dx [m]", dx)
    n = int(round(length_m / dx))
    if n < 4:
        raise RoadError(f"road of {length_m} m with spacing {dx} m has fewer than 4 samples")
    dx = length_m / n
    lo, hi = band
    if not (0 < lo < hi):
        raise RoadError(f"band must satisfy 0 < low < high, got {band}")
    if hi >= 0.5 / dx:
        raise RoadError(f"band upper edge {hi} cycle/m is at or above the Nyquist frequency "
                        f"{0.5 / dx:.4g} cycle/m of spacing {dx} m; use a smaller dx")
    k = np.arange(1, n // 2)
    nk = k / length_m
    keep = (nk + 0.5 / length_m > lo) & (nk - 0.5 / length_m < hi)
    if not np.any(keep):
        raise RoadError(f"no harmonic of a {length_m} m road falls in the band {band} cycle/m")
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0.0, 2.0 * np.pi, size=k.size)   # drawn for every bin: stable per seed
    # Each harmonic carries the PSD's exact integral over its bin [n_k - dn/2, n_k + dn/2] clipped
    # to the band, so the profile variance equals the integral of Gd over the band.
    b_lo = np.clip(nk - 0.5 / length_m, lo, hi)
    b_hi = np.clip(nk + 0.5 / length_m, lo, hi)
    var = np.array([_psd_integral(gd_n0, a, b, n0, w) for a, b in zip(b_lo, b_hi)])
    amp = np.where(keep, np.sqrt(2.0 * var), 0.0)
    spec = np.zeros(n // 2 + 1, dtype=np.complex128)
    spec[1:n // 2] = 0.5 * n * amp * np.exp(1j * phases)
    z = np.fft.irfft(spec, n)
    x = np.arange(n) * dx
    return x, z, nk[keep]


def iso8608(cls: str = "C", length_m: float = 200.0, dx: float = 0.05, seed: int = 0,
            band=ISO_BAND, gd_n0: float | None = None, w: float = ISO_W, n0: float = ISO_N0) -> Road:
    """Random profile of ISO 8608 class `cls` (or an explicit Gd(n0) [m^3]); periodic in length_m."""
    c = _check_class(cls) if gd_n0 is None else "custom"
    g = ISO_CLASSES[c] if gd_n0 is None else _positive("Gd(n0) [m^3]", gd_n0)
    x, z, grid = _harmonic_profile(length_m, dx, g, band, seed, n0, w)
    x = np.append(x, length_m)          # close the period: z(L) = z(0)
    z = np.append(z, z[0])
    return Road(f"iso8608_{c}", "spatial", x, z,
                meta=dict(input="iso8608", iso_class=c, gd_n0_m3=g, n0_cycle_m=n0, waviness=w,
                          band_cycle_m=list(band), seed=seed, length_m=length_m, dx_m=length_m / (x.size - 1),
                          n_harmonics=int(grid.size), rms_m=float(np.sqrt(np.mean(z[:-1] ** 2))),
                          rms_expected_m=math.sqrt(iso_band_variance(g, band, n0, w)),
                          synthesis="harmonics of 1/L, deterministic amplitudes, uniform random phases"))


THESIS_ROUGH_RMS_M = 0.016
THESIS_ROUGH_BASE_M = 92.0


def thesis_rough_road(seed: int = 0, dx: float = 0.05, rms_m: float = THESIS_ROUGH_RMS_M,
                      base_length_m: float = THESIS_ROUGH_BASE_M, copies: int = 2) -> Road:
    """The thesis's rough road: an ISO-shaped 92 m profile scaled to RMS 0.016 m, concatenated once (184 m)."""
    rms_m = _positive("road RMS [m]", rms_m)
    if int(copies) < 1:
        raise RoadError("copies must be >= 1")
    x, z, grid = _harmonic_profile(base_length_m, dx, 1e-6, (1.0 / base_length_m, ISO_BAND[1]),
                                   seed, ISO_N0, ISO_W)
    scale = rms_m / float(np.sqrt(np.mean(z ** 2)))
    z = z * scale
    n = x.size
    step = base_length_m / n
    xs = np.arange(n * copies + 1) * step
    zs = np.append(np.tile(z, copies), z[0])
    return Road("thesis_rough", "spatial", xs, zs,
                meta=dict(input="thesis_rough_road", rms_m=rms_m, base_length_m=base_length_m,
                          copies=int(copies), length_m=float(xs[-1]), seed=seed, dx_m=step,
                          gd_n0_m3=1e-6 * scale ** 2, iso_class_equivalent=_class_of(1e-6 * scale ** 2),
                          shape="ISO 8608 w=2 over [1/92, 2.83] cycle/m, scaled to the RMS"))


def _class_of(gd_n0: float) -> str:
    for c in ISO_CLASSES:
        if gd_n0 < iso_class_bounds(c)[1]:
            return c
    return "H"


def read_profile_csv(path: str | os.PathLike) -> Road:
    """A profile from a CSV with a header naming `distance_m` and `elevation_m` (other columns ignored)."""
    import io

    from dampnet.schema import read_text

    path = os.fspath(path)
    # read_text: a regular file of bounded size, UTF-8 with or without a BOM, errors naming the file
    # (issue 49: a BOM hid the distance_m column, a non-UTF-8 file was a traceback)
    text = read_text(path, RoadError, "UTF-8 CSV text (distance_m,elevation_m)")
    with io.StringIO(text, newline="") as f:
        rows = csv.reader(f)
        header = None
        for header in rows:
            if header and not header[0].lstrip().startswith("#") and any(h.strip() for h in header):
                break
        else:
            header = None
        if header is None:
            raise RoadError(f"{path}: empty file (expected a header 'distance_m,elevation_m')")
        names = [h.strip().lower() for h in header]
        cols = {}
        for want in ("distance_m", "elevation_m"):
            if want not in names:
                raise RoadError(f"{path}:{rows.line_num}: no column '{want}' in header {header} "
                                f"(expected 'distance_m,elevation_m', SI units)")
            cols[want] = names.index(want)
        xs, zs = [], []
        for row in rows:
            line = rows.line_num
            if not row or all(not c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            vals = []
            for want in ("distance_m", "elevation_m"):
                j = cols[want]
                cell = row[j].strip() if j < len(row) else ""
                if cell == "":
                    raise RoadError(f"{path}:{line}: column {want}: empty cell")
                try:
                    v = float(cell)
                except ValueError:
                    raise RoadError(f"{path}:{line}: column {want}: {cell!r} is not a number") from None
                if not math.isfinite(v):
                    raise RoadError(f"{path}:{line}: column {want}: {cell!r} is not finite")
                vals.append(v)
            if xs and vals[0] <= xs[-1]:
                raise RoadError(f"{path}:{line}: column distance_m: {vals[0]!r} does not increase "
                                f"(previous {xs[-1]!r})")
            xs.append(vals[0])
            zs.append(vals[1])
    if len(xs) < 2:
        raise RoadError(f"{path}: needs at least 2 data rows, got {len(xs)}")
    return Road(os.path.basename(path), "spatial", np.array(xs), np.array(zs),
                meta=dict(input="csv", path=path))

