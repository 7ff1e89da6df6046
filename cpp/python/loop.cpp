// dampnet._core.LoopModel and Loop: the quarter-car loop (dn_loop_*). A LoopModel is
// constant (vehicle, damper copy, controller); a Loop is one mutable state, one call at a
// time (BusyGuard). Loop.step returns a StepReport (step_report.cpp); Loop.simulate runs a
// whole road in C++ with the GIL released into SimulateArrays (arrays.cpp).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>

#include "arrays.hpp"
#include "busy.hpp"
#include "callback_run.hpp"
#include "common.hpp"
#include "damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/loop.hpp"
#include "fields.hpp"
#include "step_report.hpp"

namespace dnpy {

namespace {

class PyLoopModel {
 public:
  struct Deleter {
    void operator()(dn_loop_model* m) const { dn_loop_model_destroy(m); }
  };
  std::unique_ptr<dn_loop_model, Deleter> m;
  DamperRef damper;  // the Python damper, kept alive (a callback damper's function)
  dn_vehicle veh{};
  dn_controller ctrl{};

  PyLoopModel(DamperRef d, py::dict vehicle, py::dict controller) : damper(std::move(d)) {
    ctrl = controller_from(controller);
    veh = vehicle_from(vehicle);
    // the runtime's validation, naming the field (the same checks dn_loop_model_create makes)
    raise_if_invalid("LoopModel: ", vehicle, veh, controller, ctrl);
    dn_loop_model* r = nullptr;
    const int st = dn_loop_model_create(&veh, damper.d.get(), &ctrl, &r);
    if (st == DN_E_MISMATCH && dampnet::is_force_law(ctrl.kind)) {  // the runtime's refusal, in words
      std::string law = "?";
      for (const auto& k : kControllerKinds)
        if (k.value == ctrl.kind) law = k.name;
      throw py::value_error("LoopModel: controller 'kind' = " + std::to_string(ctrl.kind) + " (" + law +
                            ") tracks a force through the damper's inverse: it needs a damper whose force its "
                            "control sets (a neural model reading voltage or current, a parametric or table "
                            "damper); this damper has no control (DN_E_MISMATCH)");
    }
    check(st, "LoopModel");
    m.reset(r);
  }

  // Vectorised control law (the controller alone), for tests.
  py::array_t<double> control(DArray v_s, DArray v_us, DArray u_ext) const {
    if (v_s.size() != v_us.size() || (u_ext.size() != 1 && u_ext.size() != v_s.size()))
      throw py::value_error("control: arrays differ in length");
    py::array_t<double> u(v_s.size());
    for (py::ssize_t i = 0; i < v_s.size(); ++i)
      u.mutable_data()[i] = dampnet::control_law(ctrl, v_s.data()[i], v_us.data()[i],
                                                 u_ext.data()[u_ext.size() == 1 ? 0 : i]);
    return u;
  }
};

class PyLoop {
 public:
  struct Deleter {
    void operator()(dn_loop_data* d) const { dn_loop_data_destroy(d); }
  };
  std::shared_ptr<PyLoopModel> model;
  std::unique_ptr<dn_loop_data, Deleter> d;
  // Set while a call uses the state (BusyGuard): a Loop refuses concurrent use.
  mutable std::atomic<bool> busy{false};

  explicit PyLoop(std::shared_ptr<PyLoopModel> m) : model(m) {
    if (!model) throw py::type_error("Loop: model must be a LoopModel, not None");
    dn_loop_data* r = nullptr;
    check(dn_loop_data_create(model->m.get(), &r), "Loop");
    d.reset(r);
  }

  void reset() {
    BusyGuard guard(busy, "Loop.reset", kLoopContract);
    check(dn_loop_reset(model->m.get(), d.get()), "reset");
  }

  py::array_t<double> get_state() const {
    py::array_t<double> s(DN_LOOP_STATE_SIZE);
    BusyGuard guard(busy, "Loop.state", kLoopContract);
    dn_loop_get_state(d.get(), s.mutable_data());
    return s;
  }
  void set_state(DArray s) {
    if (s.size() != DN_LOOP_STATE_SIZE)
      throw py::value_error("state: expected " + std::to_string(DN_LOOP_STATE_SIZE) + " values");
    BusyGuard guard(busy, "Loop.state", kLoopContract);
    check(dn_loop_set_state(d.get(), s.data()), "state");
  }

  py::object step(double z_r, double v_r, double u) { return report(z_r, v_r, u, true); }

  // What step() would report, without advancing (a StepReport too).
  py::object forward(double u) { return report(0.0, 0.0, u, false); }

  py::object report(double z_r, double v_r, double u, bool advance) {
    dn_loop_input in{z_r, v_r, u};
    StepReport* rp = nullptr;
    py::object owner = new_step_report(&rp);
    StepReport& r = *rp;
    r.o = dn_loop_out{};
    {
      BusyGuard guard(busy, advance ? "Loop.step" : "Loop.forward", kLoopContract);
      CallbackRun run;
      r.status = advance ? dn_loop_step(model->m.get(), d.get(), &in, &r.o)
                         : dn_loop_forward(model->m.get(), d.get(), &in, &r.o);
      run.raise_pending();
    }
    check(r.status, advance ? "step" : "forward");
    return owner;
  }

  // The same step with the smallest Python cost: only the damper force [N] comes back
  // (no report dict), for Python code that steps the loop at a real-time rate.
  double step_force(double z_r, double v_r, double u) {
    dn_loop_input in{z_r, v_r, u};
    dn_loop_out o;
    int st;
    {
      BusyGuard guard(busy, "Loop.step_force", kLoopContract);
      CallbackRun run;
      st = dn_loop_step(model->m.get(), d.get(), &in, &o);
      run.raise_pending();
    }
    check(st, "step");
    return o.force;
  }

  // A whole road in C++ with the GIL released (see loop.py for the contract). out: None
  // (fresh arrays) or a dict with the result's keys (a previous result of the same length)
  // whose arrays are written in place and returned.
  py::dict simulate(DArray road, DArray road_rate, py::object u_obj, bool reset_first,
                    py::object out_obj) {
    if (road.ndim() != 1 || road_rate.ndim() != 1 || road.size() != road_rate.size() ||
        road.size() < 1)
      throw py::value_error("simulate: road and road_rate must be 1-D of the same length >= 1");
    const py::ssize_t n = road.size();
    // A default DArray is an empty array, not a null handle: whether u was given is has_u.
    const bool has_u = !u_obj.is_none();
    DArray u;
    if (has_u) {
      u = DArray::ensure(u_obj);
      if (!u || u.ndim() != 1 || u.size() != n)
        throw py::value_error("simulate: u must be 1-D with one value per road sample");
    }
    // A neural damper reports its inputs (dn_loop_out.n_features); the others none. (Not
    // probed with a forward call: a stateful callback damper would see an extra call.)
    const int nf = model->damper.n_features;
    auto input = [](const py::array& a) {
      const char* p = static_cast<const char*>(a.data());
      return std::make_pair(p, p + a.nbytes());
    };
    SimulateArrays res = out_obj.is_none()
        ? SimulateArrays(n, nf)
        : SimulateArrays(out_obj, n, nf,
                         {input(road), input(road_rate),
                          has_u ? input(u) : std::pair<const char*, const char*>(nullptr, nullptr)});
    double* S = res.state();
    int32_t* ST = res.status();
    const SimulateArrays::Writer write = res.writer();
    const double *R = road.data(), *RR = road_rate.data(), *UU = has_u ? u.data() : nullptr;
    const dn_loop_model* m = model->m.get();
    dn_loop_data* dd = d.get();
    py::ssize_t fail_at = -1;
    int fail_status = 0;
    BusyGuard guard(busy, "Loop.simulate", kLoopContract);
    CallbackRun run;
    {
      py::gil_scoped_release release;
      if (reset_first) dn_loop_reset(m, dd);
      double s[DN_LOOP_STATE_SIZE];
      dn_loop_get_state(dd, s);
      s[dampnet::S_z_r] = R[0];
      s[dampnet::S_v_r] = RR[0];
      fail_status = dn_loop_set_state(dd, s);
      if (fail_status < 0) fail_at = 0;
      for (py::ssize_t k = 0; k < n && fail_at < 0; ++k) {
        dn_loop_get_state(dd, S + k * DN_LOOP_STATE_SIZE);
        dn_loop_out o{};
        int st;
        if (k + 1 < n) {
          dn_loop_input in{R[k + 1], RR[k + 1], UU ? UU[k] : 0.0};
          st = dn_loop_step(m, dd, &in, &o);
        } else {
          dn_loop_input in{0.0, 0.0, UU ? UU[k] : 0.0};
          st = dn_loop_forward(m, dd, &in, &o);
        }
        ST[k] = st;
        if (st < 0) {
          fail_at = k;
          fail_status = st;
          break;
        }
        write(k, o);
      }
    }
    run.raise_pending();
    if (fail_at >= 0)
      throw py::value_error("simulate: sample " + std::to_string(fail_at) + ": " +
                            dn_status_str(fail_status));
    return res.to_dict();
  }

  int64_t damper_evals() const {
    BusyGuard guard(busy, "Loop.damper_evals", kLoopContract);
    return dn_loop_damper_evals(d.get());
  }
};

}  // namespace

void bind_loop(py::module_& mod) {
  refuse_reinit(py::class_<PyLoopModel, std::shared_ptr<PyLoopModel>>(mod, "LoopModel",
                                                        "Vehicle, damper and controller (constant): immutable, may drive Loops in many threads at once.")
      .def(py::init([](py::handle damper, py::dict vehicle, py::dict controller) {
             return std::make_shared<PyLoopModel>(
                 damper_ref(damper, "LoopModel: damper must be a Damper"), vehicle, controller);
           }),
           py::arg("damper"),
           py::arg("vehicle") = py::dict(), py::arg("controller") = py::dict())
      .def_property_readonly("vehicle", [](py::handle m) { return vehicle_dict(constructed<PyLoopModel>(m).veh); })
      .def_property_readonly("controller",
                             [](py::handle m) { return controller_dict(constructed<PyLoopModel>(m).ctrl); })
      .def("control", method(&PyLoopModel::control), py::arg("v_s"), py::arg("v_us"),
           py::arg("u_ext") = DArray(py::array_t<double>(py::ssize_t(1), std::array<double, 1>{0.0}.data())),
           "The control law alone on arrays of velocities."));

  refuse_reinit(py::class_<PyLoop>(mod, "Loop", "A loop's state (mutable) for a LoopModel. Not shareable: one call at a time; a second call "
      "while one is under way (from another thread, simulate releasing the GIL, or re-entered "
      "from a callback damper) raises RuntimeError and leaves the first undisturbed. Give each "
      "thread its own Loop(model) on a shared LoopModel.")
      .def(py::init([](py::handle model) {
             return std::make_unique<PyLoop>(shared<PyLoopModel>(model, "Loop: model must be a LoopModel"));
           }),
           py::arg("model"))
      .def("reset", method(&PyLoop::reset))
      .def_property("state", method(&PyLoop::get_state), method(&PyLoop::set_state), "Flat state (STATE_NAMES).")
      .def("step", method(&PyLoop::step), py::arg("z_r"), py::arg("v_r"), py::arg("u") = 0.0,
           "One step; road at the end of the step. Returns the report at the step start "
           "(a StepReport: attributes, or keys as in a dict).")
      .def("step_force", method(&PyLoop::step_force), py::arg("z_r"), py::arg("v_r"), py::arg("u") = 0.0,
           "One step, as step(), returning only the damper force [N] of its report (cheapest call).")
      .def("forward", method(&PyLoop::forward), py::arg("u") = 0.0, "The report without advancing.")
      .def("simulate", method(&PyLoop::simulate), py::arg("road"), py::arg("road_rate"),
           py::arg("u") = py::none(), py::arg("reset") = true, py::arg("out") = py::none(),
           "Run a road in C++ (GIL released) -> dict of arrays (fresh, or out's written in place). "
           "RuntimeError if the Loop is in use by another call; out's arrays must not be read or "
           "written by another thread during the run.")
      .def_property_readonly("model", [](py::handle l) { return constructed<PyLoop>(l).model; })
      .def_property_readonly("damper_evals", method(&PyLoop::damper_evals)));
}

}  // namespace dnpy
