// dampnet._core's Mlp: a dn_mlp owned by Python (mlp.cpp).
#pragma once

#include <pybind11/pybind11.h>

#include "dampnet/dampnet.h"

namespace dnpy {

// The C model of a constructed Mlp (TypeError for anything else); it lives as long as
// the Python object.
const dn_mlp* mlp_handle(pybind11::handle mlp);

}  // namespace dnpy
