// Which model an FMU carries: "fmu_config.h", written by python/dampnet/fmu/ next to the
// model's header, defines DNFMU_GUID (the instantiation token of modelDescription.xml) and
// DNFMU_QUARTER_CAR (1: the quarter car, 0: the damper).
#pragma once

#include "fmu_config.h"

#if DNFMU_QUARTER_CAR
#include "fmu_quarter_car.hpp"
namespace dnfmu {
using Model = QuarterCarModel;
}
#else
#include "fmu_damper.hpp"
namespace dnfmu {
using Model = DamperModel;
}
#endif

namespace dnfmu {

// One FMU instance: the model plus what the FMI wrapper keeps about the importer.
template <class Callbacks>
struct Instance {
  Model model;
  Callbacks cb;
  char name[128];
  bool model_exchange = false;
  bool initialized = false;  // after a successful exitInitializationMode: parameters fixed, steps allowed
  bool failed = false;       // exitInitializationMode failed: nothing but reset or free until a reset
  bool logging = false;
};

}  // namespace dnfmu
