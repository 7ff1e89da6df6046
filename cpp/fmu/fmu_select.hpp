// Which model an FMU carries: "fmu_config.h", written by python/dampnet/export/fmu/ next to the
// model's header, defines DNFMU_GUID (the instantiation token of modelDescription.xml) and
// DNFMU_QUARTER_CAR (1: the quarter car, 0: the damper).
#pragma once

#include <cstddef>
#include <cstdio>

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

// Steps, events and derivatives need a successful initialization (after a failed
// ExitInitializationMode the FMU is in the error state: only reset or free). False when the
// instance may go on; else true, with why in buf. fmi: "fmi2" or "fmi3", for the functions' names.
template <class I>
bool not_ready(const I& s, const char* where, const char* fmi, char* buf, std::size_t n) noexcept {
  if (s.initialized) return false;
  if (s.failed)
    std::snprintf(buf, n, "%s: the FMU is not initialized (%sExitInitializationMode failed): %sReset it and "
                  "initialize it again", where, fmi, fmi);
  else
    std::snprintf(buf, n, "%s: the FMU is not initialized: call %sExitInitializationMode first", where, fmi);
  return true;
}

}  // namespace dnfmu
