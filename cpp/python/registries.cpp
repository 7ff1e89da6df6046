// dampnet._core's description of the runtime: version, build, constants, status codes,
// and every registry of dampnet.h's X-macro lists (name lists, field docs), plus the
// vehicle / controller validation. Nothing here is retyped: each attribute is expanded
// from its list, so Python reads the names from here.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <initializer_list>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include "common.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/loop.hpp"
#include "dampnet/mlp.hpp"
#include "fields.hpp"
#include "step_report.hpp"

namespace dnpy {

namespace {

py::dict field_docs_vehicle() {
  py::dict d;
#define DN_DOC_(type, name, def, doc) d[#name] = py::make_tuple(static_cast<type>(def), doc);
  DN_VEHICLE_FIELDS(DN_DOC_)
  return d;
}

py::dict field_docs_controller() {
  py::dict d;
  DN_CONTROLLER_FIELDS(DN_DOC_)
#undef DN_DOC_
  return d;
}

// The runtime's registries (dampnet.h's X-macro lists) as module attributes, so Python
// reads every name from here instead of retyping it.
void add_registries(py::module_& mod) {
  // enum lists: {name: (value, doc)} in value order
  auto enum_dict = [](std::initializer_list<std::tuple<int, const char*, const char*>> rows) {
    py::dict d;
    for (const auto& [value, name, doc] : rows) d[name] = py::make_tuple(value, doc);
    return d;
  };
#define DNPY_ENUM_ROW_(id, value, name, doc) {int(value), name, doc},
  mod.attr("CONTROLLER_KINDS") = enum_dict({DN_CONTROLLER_KIND_LIST(DNPY_ENUM_ROW_)});
  mod.attr("INTEGRATORS") = enum_dict({DN_INTEGRATOR_LIST(DNPY_ENUM_ROW_)});
  mod.attr("DAMPER_EVALS") = enum_dict({DN_DAMPER_EVAL_LIST(DNPY_ENUM_ROW_)});
  mod.attr("ACCEL_FEATURES") = enum_dict({DN_ACCEL_FEATURE_LIST(DNPY_ENUM_ROW_)});
  mod.attr("ACTIVATIONS") = enum_dict({DN_ACTIVATION_LIST(DNPY_ENUM_ROW_)});
  mod.attr("DAMPER_KINDS") = enum_dict({DN_DAMPER_KIND_LIST(DNPY_ENUM_ROW_)});
  mod.attr("PRECISIONS") = enum_dict({DN_PRECISION_LIST(DNPY_ENUM_ROW_)});
#undef DNPY_ENUM_ROW_

  // features: the damper-input field each reads, the feature parameter each needs
  py::dict param_docs, inputs, params;
  std::vector<const char*> param_names;
#define DNPY_FPARAM_(id, name, doc) param_docs[name] = doc, param_names.push_back(name);
  DN_FEATURE_PARAM_LIST(DNPY_FPARAM_)
#undef DNPY_FPARAM_
#define DNPY_FEATURE_(id, name, field, param)                                      \
  inputs[name] = #field;                                                         \
  params[name] = (param) == DN_FPARAM_NONE ? py::object(py::none())              \
                                           : py::object(py::str(param_names[(param)]));
  DN_FEATURE_LIST(DNPY_FEATURE_)
#undef DNPY_FEATURE_
  mod.attr("FEATURE_INPUTS") = inputs;
  mod.attr("FEATURE_PARAMS") = params;
  mod.attr("FEATURE_PARAM_NAMES") = param_docs;

  // the damper's states: {name: (unit, dynamics, source field, parameter, doc)} in block order,
  // and the kinds of dynamics {name: (value, doc)}
  py::dict dyn_names;
  const char* dyn_of[8] = {};
#define DNPY_DYN_(id, value, name, doc) dyn_names[name] = py::make_tuple(int(value), doc), dyn_of[value] = name;
  DN_STATE_DYNAMICS_LIST(DNPY_DYN_)
#undef DNPY_DYN_
  mod.attr("STATE_DYNAMICS") = dyn_names;
  py::dict damper_states;
#define DNPY_DSTATE_(id, name, unit, dyn, source, param, doc) \
  damper_states[#name] = py::make_tuple(unit, dyn_of[dyn], #source, param_names[(param)], doc);
  DN_DAMPER_STATE_LIST(DNPY_DSTATE_)
#undef DNPY_DSTATE_
  mod.attr("DAMPER_STATES") = damper_states;

  py::dict damper_input;
#define DNPY_INPUT_(type, name, role, doc) damper_input[#name] = doc;
  DN_DAMPER_INPUT_FIELDS(DNPY_INPUT_)
#undef DNPY_INPUT_
  mod.attr("DAMPER_INPUT_FIELDS") = damper_input;

  // the step report's keys (Loop.step) with their docs: step_report.cpp, their one home
  mod.attr("STEP_OUTPUT_FIELDS") = step_output_fields();

  // every enum field of a vehicle or controller has its name table (checked at import)
#define DNPY_ENUM_TABLE_(type, name, def, doc) \
  if (std::is_same<type, int>::value) dnpy::enum_field(#name);
  DN_VEHICLE_FIELDS(DNPY_ENUM_TABLE_)
  DN_CONTROLLER_FIELDS(DNPY_ENUM_TABLE_)
#undef DNPY_ENUM_TABLE_
}

}  // namespace

void bind_registries(py::module_& mod) {
  mod.attr("__version__") = dn_version_string();
  mod.def("version", &dn_version, "Library version as major*10000 + minor*100 + patch.");
  mod.def("status_str", &dn_status_str, "Explain a dampnet status code.");
  {
    py::dict info;
    info["kernel_isa"] = dampnet::kernel_isa();  // the SIMD path of the kernel in this build
#ifdef DN_BUILD_FLAGS
    info["flags"] = DN_BUILD_FLAGS;
#else
    info["flags"] = "";
#endif
#ifdef DN_ISA_FLAGS
    info["isa_flags"] = DN_ISA_FLAGS;
#else
    info["isa_flags"] = "";
#endif
#ifdef DAMPNET_USE_EIGEN
    info["eigen"] = true;
#else
    info["eigen"] = false;
#endif
#if defined(__clang__)
    info["compiler"] = "clang " __clang_version__;
#elif defined(__GNUC__)
    info["compiler"] = "gcc " __VERSION__;
#else
    info["compiler"] = "unknown";
#endif
    mod.attr("BUILD_INFO") = info;
  }
  mod.attr("MAX_INPUTS") = DN_MAX_INPUTS;
  mod.attr("MAX_HIDDEN") = DN_MAX_HIDDEN;    // hidden layer 1: this build's DN_MAX_HIDDEN
  mod.attr("MAX_HIDDEN2") = DN_MAX_HIDDEN2;  // hidden layer 2
  mod.attr("MAX_HIDDEN_DEFAULT") = DN_MAX_HIDDEN_DEFAULT;  // layer 1 in a build that does not raise it
  mod.attr("DN_ACCEL_MAX_EVALS") = DN_ACCEL_MAX_EVALS;
  mod.attr("DN_INVERSE_MAX_ITERS") = DN_INVERSE_MAX_ITERS;  // Damper.inverse: its bound and tolerance
  mod.attr("DN_INVERSE_TOL_REL") = double(DN_INVERSE_TOL_REL);
  mod.attr("DN_INVERSE_WARM_EVALS") = DN_INVERSE_WARM_EVALS;  // Damper.inverse(u_start=...): its Newton steps
  {  // the physical bounds of a step's state and the step's stability limits (dampnet.h)
    py::dict bounds;
#define DNPY_PLAUSIBLE_(name, doc) bounds[#name] = py::make_tuple(double(name), doc);
    DN_PLAUSIBLE_LIST(DNPY_PLAUSIBLE_)
#undef DNPY_PLAUSIBLE_
    mod.attr("PLAUSIBLE_BOUNDS") = bounds;
    py::dict wdt;
    wdt["rk4"] = DN_STABLE_WDT_RK4;
    wdt["semi_euler"] = DN_STABLE_WDT_SEMI_EULER;
    mod.attr("STABLE_WDT") = wdt;
  }
#define DN_STATUS_ATTR_(name, value, text) mod.attr(#name) = static_cast<int>(value);
  DN_STATUS_LIST(DN_STATUS_ATTR_)
#undef DN_STATUS_ATTR_

  // ---- registries ----
  {
    py::list names;
    py::dict state_docs, out_docs;
#define DN_SNAME_(i, name, doc) names.append(#name), state_docs[#name] = doc;
    DN_LOOP_STATE_LIST(DN_SNAME_)
#undef DN_SNAME_
#define DN_DSNAME_(id, name, unit, dyn, source, param, doc) \
  names.append(#name), state_docs[#name] = std::string("damper state: ") + doc + " [" + unit + "]";
    DN_DAMPER_STATE_LIST(DN_DSNAME_)  // the damper's block, at DN_LOOP_DAMPER_BASE
#undef DN_DSNAME_
    mod.attr("STATE_NAMES") = py::tuple(names);
    mod.attr("STATE_DOCS") = state_docs;  // name -> meaning [unit], in state order
#define DN_ONAME_(name, doc) out_docs[#name] = doc;
    DN_LOOP_OUT_LIST(DN_ONAME_)
#undef DN_ONAME_
    mod.attr("LOOP_OUT_FIELDS") = out_docs;  // dn_loop_out's scalars: name -> meaning [unit]
    py::list feats;
#define DN_FNAME_(id, name, field, param) feats.append(name);
    DN_FEATURE_LIST(DN_FNAME_)
#undef DN_FNAME_
    mod.attr("FEATURE_NAMES") = py::tuple(feats);
    py::dict terms;
#define DN_TINFO_(id, value, name, n, text) terms[name] = py::make_tuple(n, text);
    DN_TERM_LIST(DN_TINFO_)
#undef DN_TINFO_
    mod.attr("TERM_KINDS") = terms;
    mod.attr("VEHICLE_FIELDS") = field_docs_vehicle();
    mod.attr("CONTROLLER_FIELDS") = field_docs_controller();
    add_registries(mod);
  }
  mod.def("check_vehicle", [](py::dict vehicle) {
    const dn_vehicle v = dnpy::vehicle_from(vehicle);
    dn_controller c;
    dn_controller_default(&c, DN_CTRL_PASSIVE);
    dnpy::raise_if_invalid("", vehicle, v, py::dict(), c);
  }, py::arg("vehicle"),
     "Validate a vehicle dict (VEHICLE_FIELDS) as LoopModel does: None, or ValueError / "
     "TypeError naming the field and its valid range or names.");
  mod.def("check_controller", [](py::dict controller) {
    const dn_controller c = dnpy::controller_from(controller);
    dn_vehicle v;
    dn_vehicle_default(&v);
    dnpy::raise_if_invalid("", py::dict(), v, controller, c);
  }, py::arg("controller"),
     "Validate a controller dict (CONTROLLER_FIELDS) as LoopModel does: None, or ValueError / "
     "TypeError naming the field and its valid range or names.");
  mod.def("force_demand", [](py::dict controller, DArray v_s, DArray v_us, DArray travel, DArray tyre) {
    const dn_controller c = dnpy::controller_from(controller);
    const DArray* arrs[] = {&v_s, &v_us, &travel, &tyre};
    py::ssize_t n = 1;
    for (const DArray* p : arrs)
      if (p->size() != 1) {
        if (n != 1 && p->size() != n) throw py::value_error("force_demand: arrays differ in length");
        n = p->size();
      }
    auto at = [](const DArray& a, py::ssize_t i) { return a.size() == 1 ? a.data()[0] : a.data()[i]; };
    py::array_t<double> f(n);
    double* fp = f.mutable_data();
    for (py::ssize_t i = 0; i < n; ++i)
      fp[i] = dampnet::force_demand(c, at(v_s, i), at(v_us, i), at(travel, i), at(tyre, i));
    return f;
  }, py::arg("controller"), py::arg("v_s"), py::arg("v_us"), py::arg("travel"), py::arg("tyre"),
     "The force [N] a force-tracking law demands of the damper, as the loop computes it each step "
     "(dn_xmacro.h DN_CONTROLLER_KIND_LIST: positive resisting extension, 0 unless dissipative, 0 "
     "for the other laws): v_s, v_us absolute velocities [m/s], travel z_s - z_us [m], tyre "
     "deflection z_us - z_r [m]; arrays broadcast to one length.");

}

}  // namespace dnpy
