"""The dyno's sensors: Gaussian noise and the recording resolution of each channel.

Noise (standard deviations, SI), typical of a crank-type shock dyno such as the
thesis's Intercomp (load cell on the eyelet; displacement and velocity from
the motor encoder / RPM):

  force        4.45 N   (1 lbf: 0.1 % of a 1000 lbf load cell, plus amplifier noise)
  displacement 25 um    (encoder and crank-linkage play, ~0.001 in)
  velocity     1 mm/s   (velocity estimated from RPM: quantised and noisy)
  voltage      2 mV     (DAQ analogue output read back)
  current      0.5 mA
  temperature  0.1 degC (K-type thermocouple after filtering)

After noise each channel is rounded to the resolution the dataset format
writes (`dampnet.data.fileformat.COLUMN_FORMATS`), as a recorder would, so
the rig's arrays survive the round trip to files unchanged.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: Recording resolution per channel (matches the file format's decimals).
RESOLUTION = {"time": 1e-7, "displacement": 1e-7, "velocity": 1e-6, "force": 1e-3,
              "voltage": 1e-4, "current": 1e-7, "temperature": 1e-3, "acceleration": 1e-5}


@dataclass
class SensorNoise:
    """Noise standard deviation per channel, SI units ([N], [m], [m/s], [V], [A], [degC])."""

    force_n: float = 4.45
    displacement_m: float = 25e-6
    velocity_m_s: float = 1e-3
    voltage_v: float = 2e-3
    current_a: float = 0.5e-3
    temperature_c: float = 0.1

    def sigma(self, channel: str) -> float:
        return {"force": self.force_n, "displacement": self.displacement_m,
                "velocity": self.velocity_m_s, "voltage": self.voltage_v,
                "current": self.current_a, "temperature": self.temperature_c}.get(channel, 0.0)

    def to_dict(self) -> dict:
        return asdict(self)


def quantise(x: np.ndarray, resolution: float) -> np.ndarray:
    """Round to a multiple of `resolution` (as the recorder and the file format do)."""
    inv = round(1.0 / resolution)
    return np.round(np.asarray(x) * inv) / inv


def measure(channel: str, x: np.ndarray, noise: SensorNoise, rng) -> np.ndarray:
    """A sensor reading of the true signal `x`: plus Gaussian noise, quantised."""
    s = noise.sigma(channel)
    y = x + rng.normal(0.0, s, size=np.shape(x)) if s > 0 else np.array(x, dtype=np.float64)
    return quantise(y, RESOLUTION.get(channel, 1e-9))


# -- recording artefacts (dampnet.data.artefacts): faults of the acquisition, put into rig data ---------

def record_artefact(ds, artefact_id: str, channel: str = "force", tests=None, *, delay_s: float = 0.010,
                    factor: float = -1.0, offset: float = 0.0):
    """A copy of the rig's dataset `ds` recorded with an artefact of dampnet.data.artefacts:

      time_offset    `channel` recorded `delay_s` [s] late (to the nearest sample)
      sign_slip      `channel` times -1 in `tests` (ids; None: every test)
      unit_slip      `channel` times `factor` in `tests` (e.g. 1000: displacement in mm)
      sensor_offset  `channel` plus `offset` (its SI unit) in `tests`

    run_order_drift has its physics in the rig (the campaign_warming effect). The artefact and its
    parameters are recorded in meta["artefacts"]; ValueError for an artefact the rig cannot record.
    """
    from dampnet.data.artefacts import artefact, flip_sign, remove_offset, rescale, shift_channel

    artefact(artefact_id)  # ValueError for an unknown id
    if artefact_id == "time_offset":
        out = shift_channel(ds, channel, float(delay_s), f"rig: {channel} recorded {delay_s:g} s late")
        params = {"channel": channel, "delay_s": float(delay_s)}
    elif artefact_id == "sign_slip":
        out, params = flip_sign(ds, channel, tests), {"channel": channel, "tests": tests}
    elif artefact_id == "unit_slip":
        out, params = rescale(ds, channel, factor, tests), {"channel": channel, "factor": factor, "tests": tests}
    elif artefact_id == "sensor_offset":
        out, params = remove_offset(ds, channel, -offset, tests), {"channel": channel, "offset": offset, "tests": tests}
    else:
        raise ValueError(f"artefact {artefact_id!r} has no recorder in the rig (run_order_drift: switch on the "
                         "campaign_warming effect)")
    out.meta["artefacts"] = {**out.meta.get("artefacts", {}), artefact_id: params}
    out.source = f"{ds.source}, artefact {artefact_id}"
    return out
