// dampnet's FMU behind the FMI 2.0 C API, co-simulation and model exchange: the model of
// fmu_select.hpp (the damper or the quarter car, with the generated model header), built by
// python/dampnet/export/fmu/ into binaries/linux64/ and shipped in sources/ so an importer elsewhere
// can rebuild it (this file is the only source to compile; include path: sources/).
// No exceptions, RTTI or operator new: the binary depends on libc and libm only.
#define DN_STATIC 1  // header-only dampnet: no import/export decoration

#include <cmath>
#include <cstring>
#include <new>

#include "fmi2Functions.h"
#include "fmu_select.hpp"

namespace {

using Inst = dnfmu::Instance<fmi2CallbackFunctions>;

void log(const Inst* s, fmi2Status status, const char* category, const char* msg) {
  if (s && s->cb.logger) s->cb.logger(s->cb.componentEnvironment, s->name, status, category, "%s", msg);
}

// A model status as an FMI status: errors are logged with the model's reason.
fmi2Status result(Inst* s, const char* where, int st) {
  if (st >= 0) return fmi2OK;
  char msg[320];
  std::snprintf(msg, sizeof msg, "%s: %s", where, s->model.message.text);
  log(s, fmi2Error, "logStatusError", msg);
  return fmi2Error;
}

Inst* inst(fmi2Component c) { return static_cast<Inst*>(c); }

// False, with the reason logged, before a successful initialization (dnfmu::not_ready).
bool ready(Inst* s, const char* where) {
  char msg[240];
  if (!dnfmu::not_ready(*s, where, "fmi2", msg, sizeof msg)) return true;
  log(s, fmi2Error, "logStatusError", msg);
  return false;
}

}  // namespace

extern "C" {

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t, const fmi2String[]) {
  if (!c) return fmi2Error;
  inst(c)->logging = on;
  return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String, const fmi2CallbackFunctions* cb,
                              fmi2Boolean, fmi2Boolean logging) {
  if (!cb || !cb->allocateMemory || !cb->freeMemory) return nullptr;
  auto fail = [&](const char* msg) -> fmi2Component {
    if (cb->logger) cb->logger(cb->componentEnvironment, name ? name : "", fmi2Error, "logStatusError", "%s", msg);
    return nullptr;
  };
  if (type != fmi2CoSimulation && type != fmi2ModelExchange)
    return fail("fmi2Instantiate: unknown fmi2Type (expected fmi2ModelExchange or fmi2CoSimulation)");
  if (!guid || std::strcmp(guid, DNFMU_GUID) != 0)
    return fail("fmi2Instantiate: GUID mismatch: the modelDescription.xml is not this binary's (expected " DNFMU_GUID ")");
  void* mem = cb->allocateMemory(1, sizeof(Inst));
  if (!mem) return fail("fmi2Instantiate: out of memory");
  Inst* s = new (mem) Inst();
  s->cb = *cb;
  std::snprintf(s->name, sizeof s->name, "%s", name ? name : "");
  s->logging = logging;
  s->model_exchange = type == fmi2ModelExchange;
  if (result(s, "fmi2Instantiate", s->model.instantiate()) != fmi2OK) {
    s->~Inst();
    cb->freeMemory(mem);
    return nullptr;
  }
  return s;
}

void fmi2FreeInstance(fmi2Component c) {
  if (!c) return;
  Inst* s = inst(c);
  const fmi2CallbackFreeMemory free_memory = s->cb.freeMemory;
  s->~Inst();
  free_memory(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean, fmi2Real, fmi2Real start, fmi2Boolean, fmi2Real) {
  if (!c) return fmi2Error;
  inst(c)->model.set_time(start);
  return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  if (!c) return fmi2Error;
  Inst* s = inst(c);
  const fmi2Status r = result(s, "fmi2ExitInitializationMode", s->model.exit_initialization(s->model_exchange));
  s->initialized = r == fmi2OK;
  s->failed = r != fmi2OK;
  return r;
}
fmi2Status fmi2Terminate(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2Reset(fmi2Component c) {
  if (!c) return fmi2Error;
  Inst* s = inst(c);
  s->initialized = false;
  s->failed = false;
  return result(s, "fmi2Reset", s->model.instantiate());
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i)
    if (result(s, "fmi2GetReal", s->model.get_real(vr[i], &value[i])) != fmi2OK) return fmi2Error;
  return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i)
    if (result(s, "fmi2GetInteger", s->model.get_int(vr[i], &value[i])) != fmi2OK) return fmi2Error;
  return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference[], size_t n, fmi2Boolean[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference[], size_t n, fmi2String[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}

// Parameters are fixed once initialized (variability="fixed"): setting one later is an error.
static fmi2Status check_settable(Inst* s, const char* where, fmi2ValueReference vr) {
  if (s->initialized && s->model.parameter(vr)) {
    char msg[200];
    std::snprintf(msg, sizeof msg, "%s: value reference %u is a fixed parameter: set it before "
                  "fmi2ExitInitializationMode", where, static_cast<unsigned>(vr));
    log(s, fmi2Error, "logStatusError", msg);
    return fmi2Error;
  }
  return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i) {
    if (check_settable(s, "fmi2SetReal", vr[i]) != fmi2OK) return fmi2Error;
    if (result(s, "fmi2SetReal", s->model.set_real(vr[i], value[i])) != fmi2OK) return fmi2Error;
  }
  return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[]) {
  if (!c || (n && (!vr || !value))) return fmi2Error;
  Inst* s = inst(c);
  for (size_t i = 0; i < n; ++i) {
    if (check_settable(s, "fmi2SetInteger", vr[i]) != fmi2OK) return fmi2Error;
    if (result(s, "fmi2SetInteger", s->model.set_int(vr[i], value[i])) != fmi2OK) return fmi2Error;
  }
  return fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference[], size_t n, const fmi2Boolean[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference[], size_t n, const fmi2String[]) {
  return c && n == 0 ? fmi2OK : fmi2Error;
}

// FMU states are not supported (canGetAndSetFMUstate="false").
fmi2Status fmi2GetFMUstate(fmi2Component, fmi2FMUstate*) { return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component, fmi2FMUstate) { return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component, fmi2FMUstate*) { return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component, fmi2FMUstate, size_t*) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component, fmi2FMUstate, fmi2Byte[], size_t) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate*) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component, const fmi2ValueReference[], size_t, const fmi2ValueReference[],
                                        size_t, const fmi2Real[], fmi2Real[]) {
  return fmi2Error;
}

// ---- Co-simulation ----
fmi2Status fmi2SetRealInputDerivatives(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[],
                                       const fmi2Real[]) {
  return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Integer[],
                                        fmi2Real[]) {
  return fmi2Error;
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean) {
  if (!c) return fmi2Error;
  Inst* s = inst(c);
  if (!ready(s, "fmi2DoStep")) return fmi2Error;
  return result(s, "fmi2DoStep", s->model.do_step(t, h));
}
fmi2Status fmi2CancelStep(fmi2Component) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component, const fmi2StatusKind, fmi2Status*) { return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Real* value) {
  if (!c || !value || kind != fmi2LastSuccessfulTime) return fmi2Discard;
  *value = inst(c)->model.time();
  return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component, const fmi2StatusKind, fmi2Integer*) { return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component, const fmi2StatusKind, fmi2Boolean*) { return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component, const fmi2StatusKind, fmi2String*) { return fmi2Discard; }

// ---- Model exchange: the model's continuous states, no event indicators; step events when the
// discrete outputs change (fmi2CompletedIntegratorStep), which take their values in event mode ----
fmi2Status fmi2EnterEventMode(fmi2Component c) { return c && ready(inst(c), "fmi2EnterEventMode") ? fmi2OK : fmi2Error; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
  if (!c || !info || !ready(inst(c), "fmi2NewDiscreteStates")) return fmi2Error;
  inst(c)->model.update_discrete();
  info->newDiscreteStatesNeeded = fmi2False;
  info->terminateSimulation = fmi2False;
  info->nominalsOfContinuousStatesChanged = fmi2False;
  info->valuesOfContinuousStatesChanged = fmi2False;
  info->nextEventTimeDefined = fmi2False;
  info->nextEventTime = 0.0;
  return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
  return c && ready(inst(c), "fmi2EnterContinuousTimeMode") ? fmi2OK : fmi2Error;
}
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean, fmi2Boolean* enter_event, fmi2Boolean* terminate) {
  if (!c || !enter_event || !terminate || !ready(inst(c), "fmi2CompletedIntegratorStep")) return fmi2Error;
  *enter_event = inst(c)->model.step_event() ? fmi2True : fmi2False;
  *terminate = fmi2False;
  return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
  if (!c) return fmi2Error;
  inst(c)->model.set_time(t);
  return fmi2OK;
}
static bool states_match(Inst* s, size_t nx, const char* where) {
  if (nx == static_cast<size_t>(s->model.n_states())) return true;
  char msg[160];
  std::snprintf(msg, sizeof msg, "%s: %zu continuous states given, the model has %d", where, nx, s->model.n_states());
  log(s, fmi2Error, "logStatusError", msg);
  return false;
}
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
  if (!c || (nx && !x) || !states_match(inst(c), nx, "fmi2SetContinuousStates")) return fmi2Error;
  inst(c)->model.set_states(x);
  return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
  if (!c || (nx && !dx) || !states_match(inst(c), nx, "fmi2GetDerivatives")) return fmi2Error;
  if (inst(c)->failed && !ready(inst(c), "fmi2GetDerivatives")) return fmi2Error;
  return result(inst(c), "fmi2GetDerivatives", inst(c)->model.derivatives(dx));
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real[], size_t ni) { return c && ni == 0 ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
  if (!c || (nx && !x) || !states_match(inst(c), nx, "fmi2GetContinuousStates")) return fmi2Error;
  inst(c)->model.get_states(x);
  return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
  if (!c || (nx && !x) || !states_match(inst(c), nx, "fmi2GetNominalsOfContinuousStates")) return fmi2Error;
  for (size_t i = 0; i < nx; ++i) x[i] = 1.0;
  return fmi2OK;
}

}  // extern "C"
