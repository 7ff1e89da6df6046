"""What the truth damper's force laws see, per sample: the Context shared by truth.py and effects.py.

Its own module so that the effects (which read it) and the truth damper (which runs the
effects) both import it, and neither imports the other's caller.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Context:
    """What the force laws see, per sample (arrays along the last axis)."""

    x: np.ndarray            # displacement [m]
    v: np.ndarray            # velocity [m/s]
    voltage: np.ndarray      # control voltage [V]
    temperature: np.ndarray  # oil temperature [degC]
    dt: float                # sample interval [s]
    params: Any              # dampnet.rig.truth.TruthParams
    current: np.ndarray = None   # controller current [A]
    opening: np.ndarray = None   # valve opening [0..1]
    v_h: np.ndarray = None       # velocity seen by the hydraulics [m/s]
    parts: dict = field(default_factory=dict)   # named force components [N]
