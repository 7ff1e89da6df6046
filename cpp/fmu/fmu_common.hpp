// What every dampnet FMU model shares: the error message buffer, the status text, and the
// contract the FMI wrappers (fmu2.cpp, fmu3.cpp) rely on.
//
// A model (DamperModel in fmu_damper.hpp, QuarterCarModel in fmu_quarter_car.hpp) is one
// plain struct, placement-constructed in memory from the importer's allocator, with:
//   int  instantiate()                 load the generated model header; parameters at their starts
//   int  exit_initialization(bool me)  apply the parameters (validated), set the initial states
//   void reset()                       back to the state after instantiate()
//   int  get_real(vr, double*) / set_real(vr, double)        Real (FMI 2) / Float64 (FMI 3)
//   int  get_int(vr, int*)     / set_int(vr, int)            Integer / Int32
//   int  do_step(t, h)                 co-simulation: advance from t to t + h
//   void set_time(t)                   model exchange
//   int  n_states(), get_states(x), set_states(x), derivatives(dx)    model exchange
//   bool step_event()                  model exchange, after an integrator step: the discrete
//                                      outputs would change (the importer enters event mode)
//   void update_discrete()             model exchange, event mode: the discrete outputs take
//                                      their values at this instant (they hold between events)
//   bool parameter(vr)                 the value reference is a parameter (settable before init only)
//   bool enumeration(vr)               the value reference is an Enumeration (FMI 3: Int64 access)
// Every int return is a dampnet status (< 0: error, with the reason in `message`).
// Nothing here allocates, throws or uses RTTI: the binary needs libc and libm only.
#pragma once

#include <cstdarg>
#include <cstdio>

#include "dampnet/dampnet.h"
#include "dampnet/envelope.hpp"
#include "fmu_model.h"  // the generated model header: FMU_MODEL_HAS_ENVELOPE below

namespace dnfmu {

// The model's training envelope for the envelope_flags output: the generated header's grid
// when the model was exported with its envelope (FMU_MODEL_HAS_ENVELOPE), else its training
// ranges alone (then only DN_ENV_OUTSIDE_RANGE can be set).
inline int load_envelope(dampnet::Envelope& env, const dn_mlp_desc& model) noexcept {
#ifdef FMU_MODEL_HAS_ENVELOPE
  (void)model;
  const dn_envelope_desc d = FMU_MODEL_ENVELOPE_DESC_INIT;
  return env.load(&d);
#else
  return env.load_ranges(model.n_inputs, model.sat_lo, model.sat_hi);
#endif
}

// The reason for the last error, in words, for the importer's logger.
struct Message {
  char text[256] = {0};
  int fail(int status, const char* fmt, ...) noexcept __attribute__((format(printf, 3, 4))) {
    va_list ap;
    va_start(ap, fmt);
    std::vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    return status;
  }
};

// dn_status_str without the library (the FMU binary is header-only dampnet).
inline const char* status_text(int st) noexcept {
#define DNFMU_STATUS_CASE_(name, value, text) \
  if (st == (value)) return text;
  DN_STATUS_LIST(DNFMU_STATUS_CASE_)
#undef DNFMU_STATUS_CASE_
  return "unknown dampnet status";
}

// Value-reference errors share one message.
inline int no_such(Message& m, const char* what, unsigned vr) noexcept {
  return m.fail(DN_E_PARAM, "no %s variable with value reference %u", what, vr);
}

}  // namespace dnfmu
