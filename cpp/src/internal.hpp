// Definitions of the C ABI's opaque handles, shared by the C ABI sources.
#pragma once

#include "dampnet/damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/loop.hpp"
#include "dampnet/mlp.hpp"

struct dn_mlp {
  dampnet::Mlp<double> md;
  dampnet::Mlp<float> mf;
};

struct dn_damper {
  dampnet::Damper d;
};

struct dn_loop_model {
  dampnet::LoopModel m;
};

struct dn_loop_data {
  dampnet::LoopData d;
};
