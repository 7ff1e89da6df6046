// dampnet._core: the pybind11 front door to the C++ runtime. This file only creates the
// module; each object is bound by its own part (common.hpp lists them):
//   registries.cpp   version, build info, constants, status codes, dampnet.h's name lists
//   mlp.cpp          Mlp
//   damper.cpp       DamperInput, Damper
//   step_report.cpp  StepReport (a hand-built CPython type)
//   loop.cpp         LoopModel, Loop (simulate's arrays: arrays.cpp, huge_pages.cpp)
//   fullcar.cpp      FullCarModel, FullCar (the full vehicle)
//   envelope.cpp     Envelope (the training envelope's bounded-time check)
// Shared: common.hpp (status -> exception, safe self access), fields.hpp (dict <-> struct),
// busy.hpp (one call at a time on a Loop), callback_run.hpp (a callback's exception).
#include <pybind11/pybind11.h>

#include "common.hpp"

PYBIND11_MODULE(_core, mod) {
  mod.doc() =
      "dampnet C++ runtime (MLP kernel, quarter-car loop).\n\n"
      "Threading: Mlp, Damper and LoopModel are immutable once built and may be shared by "
      "threads; a Loop is one mutable loop state: one call at a time (a second call while one "
      "is under way raises RuntimeError), so give each thread its own Loop on a shared model. "
      "Loop.simulate, Mlp.predict and Damper.forces release the GIL (callback dampers hold it).";
  dnpy::bind_registries(mod);
  dnpy::bind_mlp(mod);
  dnpy::bind_damper(mod);
  dnpy::bind_step_report(mod);
  dnpy::bind_loop(mod);
  dnpy::bind_fullcar(mod);
  dnpy::bind_envelope(mod);
}
