// Definitions of the C ABI's opaque handles, shared by the C ABI sources.
#pragma once

#include "dampnet/damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/fullcar.hpp"
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

struct dn_fullcar_model {
  dampnet::FullCarModel m;
};

struct dn_fullcar_data {
  dampnet::FullCarData d;
};
