"""The virtual shock dynamometer: a physical truth damper, switchable effects, test plans, sensors.

  truth.py    the damper's physics (TruthParams, truth_force, TruthDamper)
  context.py  what the force laws see per sample (Context), shared by truth.py and effects.py
  effects.py  the switchable effects' physics (EFFECTS: gas_spring, thermal, valve_lag, friction,
              bump_stop), keyed by the effect catalogue dampnet.effects
  plans.py    test plans (thesis, quick, JSON files)
  sensors.py  noise, recording resolution, and recording artefacts (record_artefact)
  generate.py the rig itself (generate, noise_floor_nrmse, noise_floor_rmse_n)
"""

from dampnet.rig.effects import EFFECTS, Effect, register
from dampnet.rig.generate import generate, noise_floor_nrmse, noise_floor_rmse_n
from dampnet.rig.plans import Plan, load_plan, quick_plan, thesis_plan
from dampnet.rig.sensors import RESOLUTION, SensorNoise
from dampnet.rig.truth import (TruthDamper, TruthParams, controller_current, truth_force,
                                    valve_opening)

__all__ = ["EFFECTS", "Effect", "register", "generate", "noise_floor_nrmse", "noise_floor_rmse_n", "Plan", "load_plan",
           "quick_plan", "thesis_plan", "RESOLUTION", "SensorNoise", "TruthDamper", "TruthParams",
           "controller_current", "truth_force", "valve_opening"]
