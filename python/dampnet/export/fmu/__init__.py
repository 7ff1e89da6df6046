"""The model as an FMU (FMI 2.0 or 3.0; co-simulation, model exchange or both), for the
vehicle-simulation tools that import FMUs (CarSim, CarMaker, Simulink, Dymola, OpenModelica,
Silver, FMPy, ...).

`build_fmu(model, out, fmi=2, interface="both", what="damper")` writes the model's header
(dampnet.export.header_text), modelDescription.xml and compiles cpp/fmu/fmu2.cpp or fmu3.cpp
(dampnet's header-only runtime behind the FMI C API; FMI headers 2-clause BSD, in cpp/fmu/fmi2,
fmi3) into binaries/<platform>/, with the sources in sources/ (and sources/buildDescription.xml
for FMI 3) so an importer elsewhere can rebuild it. The binary depends on libc and libm only.

- what="damper" (damper.py): inputs x [m], v [m/s], a [m/s2], u, temperature [degC] and
  force_demand [N]; outputs force [N], status, clamped_mask, envelope_flags (with `envelope`, the
  training envelope's bounded-time check, dampnet.envelope.grid; without, the training ranges
  only), and the damper's inverse of force_demand at the current motion: u_command [the control's
  unit], inverse_status, force_at_command [N]; parameters the feature constants and physics terms;
  the derived features' states advance exactly as in dampnet's loop (cpp/fmu/fmu_damper.hpp).
- what="quarter-car" (quarter_car.py): co-simulation only; road in, the quarter car's motion out.
"""

from __future__ import annotations

import os
from pathlib import Path

from dampnet.export.fmu.damper import FMU_FEATURES, MODEL_IDENTIFIER, FmuError, check_model, damper_description
from dampnet.model import MlpModel

WHATS = ("damper", "quarter-car")

__all__ = ["FMU_FEATURES", "MODEL_IDENTIFIER", "WHATS", "FmuError", "build_damper_fmu", "build_fmu", "check_model"]


def build_fmu(model: MlpModel, out: str | os.PathLike, fmi: int = 2, interface: str | None = None,
              what: str = "damper", overwrite: bool = False, vehicle: dict | None = None,
              controller: dict | None = None, envelope=None, law: str | None = None) -> Path:
    """Build OUT.fmu (see the module docstring); built in a scratch directory of the system's
    temporary directory and written atomically (a missing parent directory is created), so a
    failure or a kill leaves nothing half-written. interface: "cs", "me" or "both"
    (default: both for the damper, cs for the quarter car). vehicle / controller: the quarter
    car's parameter start values (dampnet.sim.vehicle field names; defaults Table 5, passive);
    law: the name of the control law that calibrated `controller` (dampnet.recipes.control_laws),
    for the FMU's description.
    envelope: the model's dampnet.envelope.Envelope, for the envelope_flags output's grid."""
    from dampnet.export.fmu.build import package

    if what == "damper":
        if vehicle or controller:
            raise FmuError("vehicle and controller parameters belong to the quarter-car FMU (what='quarter-car')")
        return package(model, damper_description(model, envelope is not None), out, fmi, interface, False,
                       overwrite, envelope)
    if what == "quarter-car":
        from dampnet.export.fmu.quarter_car import quarter_car_description

        return package(model, quarter_car_description(model, vehicle, controller, envelope is not None, law), out, fmi,
                       interface, True, overwrite, envelope)
    raise FmuError(f"what={what!r}: expected one of {', '.join(WHATS)}")


def build_damper_fmu(model: MlpModel, out: str | os.PathLike, overwrite: bool = False, fmi: int = 2,
                     interface: str | None = None, envelope=None) -> Path:
    """The damper FMU (build_fmu with what='damper')."""
    return build_fmu(model, out, fmi=fmi, interface=interface, what="damper", overwrite=overwrite, envelope=envelope)
