// dampnet._core's Damper: a dn_damper owned by Python (damper.cpp).
#pragma once

#include <pybind11/pybind11.h>

#include <memory>

#include "dampnet/dampnet.h"

namespace dnpy {

// What a loop model needs of a constructed Damper (TypeError for anything else): the C
// damper, kept alive by the pointer (a callback damper's function lives in the Python
// object, which this pointer owns a share of), and the number of a neural damper's inputs
// (0 for the others).
struct DamperRef {
  std::shared_ptr<const dn_damper> d;
  int n_features = 0;
};
DamperRef damper_ref(pybind11::handle damper, const char* what);

}  // namespace dnpy
