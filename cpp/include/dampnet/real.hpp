// The loop's real type, dn_real (dampnet.h: double, or float with DN_LOOP_FLOAT), in C++.
#pragma once

#include "dampnet/dampnet.h"

namespace dampnet {

using real = dn_real;

// A constant in the loop's precision: R(0.5) is 0.5 in a double build and 0.5f in a float one,
// so that a float build computes in float throughout (a bare 0.5 would promote every operand
// to double; cpp/embedded/float_loop_check.cpp compiles the loop with -Wdouble-promotion).
constexpr real R(double x) noexcept { return static_cast<real>(x); }

}  // namespace dampnet
