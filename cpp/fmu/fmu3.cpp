// dampnet's FMU behind the FMI 3.0 C API, co-simulation and model exchange: the model of
// fmu_select.hpp (the damper or the quarter car, with the generated model header), built by
// python/dampnet/export/fmu/ into binaries/x86_64-linux/ and shipped in sources/ with
// buildDescription.xml (this file is the only source to compile; include path: sources/).
// Float64, Int32 and Enumeration (Int64 access) variables only; no clocks, no event indicators
// (model exchange: step events when the discrete outputs change), no FMU state, no scheduled
// execution.
// The instance is allocated with calloc at instantiation (FMI 3 has no allocator callbacks);
// nothing else allocates. No exceptions or RTTI: the binary depends on libc and libm only.
#define DN_STATIC 1  // header-only dampnet: no import/export decoration

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <new>

#include "fmi3Functions.h"
#include "fmu_select.hpp"

namespace {

struct Callbacks {
  fmi3InstanceEnvironment env = nullptr;
  fmi3LogMessageCallback log = nullptr;
};
using Inst = dnfmu::Instance<Callbacks>;

void log(const Inst* s, fmi3Status status, const char* category, const char* msg) {
  if (s && s->cb.log) s->cb.log(s->cb.env, status, category, msg);
}

fmi3Status result(Inst* s, const char* where, int st) {
  if (st >= 0) return fmi3OK;
  char msg[320];
  std::snprintf(msg, sizeof msg, "%s: %s", where, s->model.message.text);
  log(s, fmi3Error, "logStatusError", msg);
  return fmi3Error;
}

Inst* inst(fmi3Instance c) { return static_cast<Inst*>(c); }

// False, with the reason logged, before a successful initialization (dnfmu::not_ready).
bool ready(Inst* s, const char* where) {
  char msg[240];
  if (!dnfmu::not_ready(*s, where, "fmi3", msg, sizeof msg)) return true;
  log(s, fmi3Error, "logStatusError", msg);
  return false;
}

// Enumerations are accessed as Int64 (FMI 3), the other integers as Int32: the wrong one is an error.
bool typed(Inst* s, const char* where, fmi3ValueReference vr, bool as_enumeration) {
  if (s->model.enumeration(vr) == as_enumeration) return true;
  char msg[200];
  std::snprintf(msg, sizeof msg, "%s: value reference %u is %s", where, static_cast<unsigned>(vr),
                as_enumeration ? "not an Enumeration (use the Int32 or Float64 functions)"
                               : "an Enumeration: use fmi3GetInt64 / fmi3SetInt64");
  log(s, fmi3Error, "logStatusError", msg);
  return false;
}

fmi3Instance instantiate(fmi3String name, fmi3String token, fmi3Boolean logging, fmi3InstanceEnvironment env,
                         fmi3LogMessageCallback logger, bool model_exchange) {
  auto fail = [&](const char* msg) -> fmi3Instance {
    if (logger) logger(env, fmi3Error, "logStatusError", msg);
    return nullptr;
  };
  if (!token || std::strcmp(token, DNFMU_GUID) != 0)
    return fail("fmi3Instantiate: instantiationToken mismatch: the modelDescription.xml is not this binary's "
                "(expected " DNFMU_GUID ")");
  void* mem = std::calloc(1, sizeof(Inst));
  if (!mem) return fail("fmi3Instantiate: out of memory");
  Inst* s = new (mem) Inst();
  s->cb.env = env;
  s->cb.log = logger;
  std::snprintf(s->name, sizeof s->name, "%s", name ? name : "");
  s->logging = logging;
  s->model_exchange = model_exchange;
  if (result(s, "fmi3Instantiate", s->model.instantiate()) != fmi3OK) {
    s->~Inst();
    std::free(mem);
    return nullptr;
  }
  return s;
}

fmi3Status check_settable(Inst* s, const char* where, fmi3ValueReference vr) {
  if (s->initialized && s->model.parameter(vr)) {
    char msg[200];
    std::snprintf(msg, sizeof msg, "%s: value reference %u is a fixed parameter: set it before "
                  "fmi3ExitInitializationMode", where, static_cast<unsigned>(vr));
    log(s, fmi3Error, "logStatusError", msg);
    return fmi3Error;
  }
  return fmi3OK;
}

// Int32 (status, clamped_mask, envelope_flags) and Int64 (the Enumerations) through the model's
// get_int / set_int; each type reaches its own variables only.
template <class T>
fmi3Status get_ints(fmi3Instance c, const fmi3ValueReference vr[], size_t n, T value[], size_t nv, const char* where,
                    bool enumeration) {
  if (!c || n != nv || (n && (!vr || !value))) return fmi3Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i) {
    int v = 0;
    if (!typed(s, where, vr[i], enumeration)) return fmi3Error;
    if (result(s, where, s->model.get_int(vr[i], &v)) != fmi3OK) return fmi3Error;
    value[i] = v;
  }
  return fmi3OK;
}
template <class T>
fmi3Status set_ints(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const T value[], size_t nv,
                    const char* where, bool enumeration) {
  if (!c || n != nv || (n && (!vr || !value))) return fmi3Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i) {
    if (!typed(s, where, vr[i], enumeration)) return fmi3Error;
    if (check_settable(s, where, vr[i]) != fmi3OK) return fmi3Error;
    // an Int64 beyond int is no item of any enumeration: clamped, it is refused at initialisation
    const int64_t w = value[i];
    const int v = w < INT32_MIN ? INT32_MIN : w > INT32_MAX ? INT32_MAX : static_cast<int>(w);
    if (result(s, where, s->model.set_int(vr[i], v)) != fmi3OK) return fmi3Error;
  }
  return fmi3OK;
}

bool states_match(Inst* s, size_t nx, const char* where) {
  if (nx == static_cast<size_t>(s->model.n_states())) return true;
  char msg[160];
  std::snprintf(msg, sizeof msg, "%s: %zu continuous states given, the model has %d", where, nx, s->model.n_states());
  log(s, fmi3Error, "logStatusError", msg);
  return false;
}

}  // namespace

extern "C" {

const char* fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t, const fmi3String[]) {
  if (!c) return fmi3Error;
  inst(c)->logging = on;
  return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String, fmi3Boolean,
                                          fmi3Boolean logging, fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback logger) {
  return instantiate(name, token, logging, env, logger, true);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String, fmi3Boolean,
                                         fmi3Boolean logging, fmi3Boolean event_mode, fmi3Boolean early_return,
                                         const fmi3ValueReference[], size_t, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logger, fmi3IntermediateUpdateCallback) {
  if (event_mode && logger)  // hasEventMode="false": the importer may not ask for it
    logger(env, fmi3Warning, "logStatusWarning", "fmi3InstantiateCoSimulation: event mode is not supported; ignored");
  (void)early_return;  // never returns early
  return instantiate(name, token, logging, env, logger, false);
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String, fmi3String, fmi3Boolean, fmi3Boolean,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback logger,
                                               fmi3ClockUpdateCallback, fmi3LockPreemptionCallback,
                                               fmi3UnlockPreemptionCallback) {
  (void)name;
  if (logger) logger(env, fmi3Error, "logStatusError", "fmi3InstantiateScheduledExecution: not supported");
  return nullptr;
}

void fmi3FreeInstance(fmi3Instance c) {
  if (!c) return;
  inst(c)->~Inst();
  std::free(c);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean, fmi3Float64, fmi3Float64 start, fmi3Boolean,
                                       fmi3Float64) {
  if (!c) return fmi3Error;
  inst(c)->model.set_time(start);
  return fmi3OK;
}
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
  if (!c) return fmi3Error;
  Inst* s = inst(c);
  const fmi3Status r = result(s, "fmi3ExitInitializationMode", s->model.exit_initialization(s->model_exchange));
  s->initialized = r == fmi3OK;
  s->failed = r != fmi3OK;
  return r;
}
fmi3Status fmi3EnterEventMode(fmi3Instance c) { return c && ready(inst(c), "fmi3EnterEventMode") ? fmi3OK : fmi3Error; }
fmi3Status fmi3Terminate(fmi3Instance c) { return c ? fmi3OK : fmi3Error; }
fmi3Status fmi3Reset(fmi3Instance c) {
  if (!c) return fmi3Error;
  Inst* s = inst(c);
  s->initialized = false;
  s->failed = false;
  return result(s, "fmi3Reset", s->model.instantiate());
}

// ---- Getters and setters: Float64, Int32 and Int64 (Enumerations); the other types have no variables ----
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 value[], size_t nv) {
  if (!c || n != nv || (n && (!vr || !value))) return fmi3Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i) {
    if (vr[i] == DNFMU_VR_TIME) {
      value[i] = s->model.time();
      continue;
    }
    if (result(s, "fmi3GetFloat64", s->model.get_real(vr[i], &value[i])) != fmi3OK) return fmi3Error;
  }
  return fmi3OK;
}
fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Int32 value[], size_t nv) {
  return get_ints(c, vr, n, value, nv, "fmi3GetInt32", false);
}
fmi3Status fmi3GetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Int64 value[], size_t nv) {
  return get_ints(c, vr, n, value, nv, "fmi3GetInt64", true);
}
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 value[],
                          size_t nv) {
  if (!c || n != nv || (n && (!vr || !value))) return fmi3Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i) {
    if (check_settable(s, "fmi3SetFloat64", vr[i]) != fmi3OK) return fmi3Error;
    if (result(s, "fmi3SetFloat64", s->model.set_real(vr[i], value[i])) != fmi3OK) return fmi3Error;
  }
  return fmi3OK;
}
fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int32 value[], size_t nv) {
  return set_ints(c, vr, n, value, nv, "fmi3SetInt32", false);
}
fmi3Status fmi3SetInt64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Int64 value[], size_t nv) {
  return set_ints(c, vr, n, value, nv, "fmi3SetInt64", true);
}

#define DNFMU_NO_VARIABLES_(Type, CType)                                                                  \
  fmi3Status fmi3Get##Type(fmi3Instance c, const fmi3ValueReference[], size_t n, CType[], size_t) {       \
    return c && n == 0 ? fmi3OK : fmi3Error;                                                              \
  }                                                                                                       \
  fmi3Status fmi3Set##Type(fmi3Instance c, const fmi3ValueReference[], size_t n, const CType[], size_t) { \
    return c && n == 0 ? fmi3OK : fmi3Error;                                                              \
  }
DNFMU_NO_VARIABLES_(Float32, fmi3Float32)
DNFMU_NO_VARIABLES_(Int8, fmi3Int8)
DNFMU_NO_VARIABLES_(UInt8, fmi3UInt8)
DNFMU_NO_VARIABLES_(Int16, fmi3Int16)
DNFMU_NO_VARIABLES_(UInt16, fmi3UInt16)
DNFMU_NO_VARIABLES_(UInt32, fmi3UInt32)
DNFMU_NO_VARIABLES_(UInt64, fmi3UInt64)
DNFMU_NO_VARIABLES_(Boolean, fmi3Boolean)
DNFMU_NO_VARIABLES_(String, fmi3String)
#undef DNFMU_NO_VARIABLES_
fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference[], size_t n, size_t[], fmi3Binary[], size_t) {
  return c && n == 0 ? fmi3OK : fmi3Error;
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference[], size_t n, const size_t[], const fmi3Binary[],
                         size_t) {
  return c && n == 0 ? fmi3OK : fmi3Error;
}
fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference[], size_t n, fmi3Clock[]) {
  return c && n == 0 ? fmi3OK : fmi3Error;
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference[], size_t n, const fmi3Clock[]) {
  return c && n == 0 ? fmi3OK : fmi3Error;
}

// ---- Not supported (the modelDescription says so) ----
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance, fmi3ValueReference, size_t*) { return fmi3Error; }
fmi3Status fmi3GetVariableDependencies(fmi3Instance, fmi3ValueReference, size_t[], fmi3ValueReference[], size_t[],
                                       fmi3DependencyKind[], size_t) {
  return fmi3Error;
}
fmi3Status fmi3GetFMUState(fmi3Instance, fmi3FMUState*) { return fmi3Error; }
fmi3Status fmi3SetFMUState(fmi3Instance, fmi3FMUState) { return fmi3Error; }
fmi3Status fmi3FreeFMUState(fmi3Instance, fmi3FMUState*) { return fmi3Error; }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance, fmi3FMUState, size_t*) { return fmi3Error; }
fmi3Status fmi3SerializeFMUState(fmi3Instance, fmi3FMUState, fmi3Byte[], size_t) { return fmi3Error; }
fmi3Status fmi3DeserializeFMUState(fmi3Instance, const fmi3Byte[], size_t, fmi3FMUState*) { return fmi3Error; }
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3ValueReference[],
                                        size_t, const fmi3Float64[], size_t, fmi3Float64[], size_t) {
  return fmi3Error;
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3ValueReference[],
                                    size_t, const fmi3Float64[], size_t, fmi3Float64[], size_t) {
  return fmi3Error;
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance) { return fmi3Error; }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance) { return fmi3Error; }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance, const fmi3ValueReference[], size_t, fmi3Float64[],
                                  fmi3IntervalQualifier[]) {
  return fmi3Error;
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance, const fmi3ValueReference[], size_t, fmi3UInt64[], fmi3UInt64[],
                                   fmi3IntervalQualifier[]) {
  return fmi3Error;
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance, const fmi3ValueReference[], size_t, fmi3Float64[]) { return fmi3Error; }
fmi3Status fmi3GetShiftFraction(fmi3Instance, const fmi3ValueReference[], size_t, fmi3UInt64[], fmi3UInt64[]) {
  return fmi3Error;
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Float64[]) {
  return fmi3Error;
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3UInt64[],
                                   const fmi3UInt64[]) {
  return fmi3Error;
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Float64[]) {
  return fmi3Error;
}
fmi3Status fmi3SetShiftFraction(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3UInt64[],
                                const fmi3UInt64[]) {
  return fmi3Error;
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) {
  if (!c || !ready(inst(c), "fmi3EvaluateDiscreteStates")) return fmi3Error;
  inst(c)->model.update_discrete();
  return fmi3OK;
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance, fmi3ValueReference, fmi3Float64) { return fmi3Error; }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean* update, fmi3Boolean* terminate,
                                    fmi3Boolean* nominals_changed, fmi3Boolean* values_changed,
                                    fmi3Boolean* next_defined, fmi3Float64* next_time) {
  if (!c || !ready(inst(c), "fmi3UpdateDiscreteStates")) return fmi3Error;
  inst(c)->model.update_discrete();
  if (update) *update = fmi3False;
  if (terminate) *terminate = fmi3False;
  if (nominals_changed) *nominals_changed = fmi3False;
  if (values_changed) *values_changed = fmi3False;
  if (next_defined) *next_defined = fmi3False;
  if (next_time) *next_time = 0.0;
  return fmi3OK;
}

// ---- Model exchange: the model's continuous states, no event indicators; step events when the
// discrete outputs change (fmi3CompletedIntegratorStep), which take their values in event mode ----
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
  return c && ready(inst(c), "fmi3EnterContinuousTimeMode") ? fmi3OK : fmi3Error;
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean, fmi3Boolean* enter_event, fmi3Boolean* terminate) {
  if (!c || !enter_event || !terminate || !ready(inst(c), "fmi3CompletedIntegratorStep")) return fmi3Error;
  *enter_event = inst(c)->model.step_event() ? fmi3True : fmi3False;
  *terminate = fmi3False;
  return fmi3OK;
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) {
  if (!c) return fmi3Error;
  inst(c)->model.set_time(t);
  return fmi3OK;
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t nx) {
  if (!c || (nx && !x) || !states_match(inst(c), nx, "fmi3SetContinuousStates")) return fmi3Error;
  inst(c)->model.set_states(x);
  return fmi3OK;
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t nx) {
  if (!c || (nx && !dx) || !states_match(inst(c), nx, "fmi3GetContinuousStateDerivatives")) return fmi3Error;
  if (inst(c)->failed && !ready(inst(c), "fmi3GetContinuousStateDerivatives")) return fmi3Error;
  return result(inst(c), "fmi3GetContinuousStateDerivatives", inst(c)->model.derivatives(dx));
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64[], size_t ni) { return c && ni == 0 ? fmi3OK : fmi3Error; }
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
  if (!c || (nx && !x) || !states_match(inst(c), nx, "fmi3GetContinuousStates")) return fmi3Error;
  inst(c)->model.get_states(x);
  return fmi3OK;
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
  if (!c || (nx && !x) || !states_match(inst(c), nx, "fmi3GetNominalsOfContinuousStates")) return fmi3Error;
  for (size_t i = 0; i < nx; ++i) x[i] = 1.0;
  return fmi3OK;
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t* n) {
  if (!c || !n) return fmi3Error;
  *n = 0;
  return fmi3OK;
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t* n) {
  if (!c || !n) return fmi3Error;
  *n = static_cast<size_t>(inst(c)->model.n_states());
  return fmi3OK;
}

// ---- Co-simulation ----
fmi3Status fmi3EnterStepMode(fmi3Instance c) { return c ? fmi3OK : fmi3Error; }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance, const fmi3ValueReference[], size_t, const fmi3Int32[], fmi3Float64[],
                                    size_t) {
  return fmi3Error;
}
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean, fmi3Boolean* event_needed,
                      fmi3Boolean* terminate, fmi3Boolean* early_return, fmi3Float64* last_time) {
  if (!c) return fmi3Error;
  Inst* s = inst(c);
  if (!ready(s, "fmi3DoStep")) return fmi3Error;
  if (event_needed) *event_needed = fmi3False;
  if (terminate) *terminate = fmi3False;
  if (early_return) *early_return = fmi3False;
  const fmi3Status r = result(s, "fmi3DoStep", s->model.do_step(t, h));
  if (last_time) *last_time = s->model.time();
  return r;
}

}  // extern "C"
