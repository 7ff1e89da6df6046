// FullCarModel and FullCar: the full vehicle (cpp/include/dampnet/fullcar.hpp) from Python,
// through the C ABI as Loop is. A FullCar is one mutable state: one call at a time
// (BusyGuard), like a Loop. FullCar.simulate runs a whole road in C++ with the GIL released.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "busy.hpp"
#include "callback_run.hpp"
#include "common.hpp"
#include "damper.hpp"
#include "dampnet/dampnet.h"
#include "dampnet/fullcar.hpp"
#include "fields.hpp"

namespace dnpy {

namespace {

constexpr int kN = DN_FULLCAR_CORNERS;
const char* const kCornerNames[kN] = {"fl", "fr", "rl", "rr"};

inline constexpr const char* kFullCarContract =
    "a FullCar holds one mutable vehicle state and must not be used by two calls at once: give "
    "each thread its own FullCar(model); a FullCarModel, Damper and Mlp are immutable and may be "
    "shared between threads";

dn_fullcar_params fullcar_from(const py::dict& d, const char* what) {
  dn_fullcar_params p;
  dn_fullcar_default(&p);
  set_fullcar_fields(p, d, what);
  return p;
}

// Validation naming the field: the first given one that, put back to its default, makes the
// parameters valid; else the first given one that alone, on the defaults, is invalid.
void raise_if_invalid_fullcar(const char* what, const py::dict& given, const dn_fullcar_params& p) {
  const int st = dn_fullcar_check(&p);
  if (st >= 0) return;
  dn_fullcar_params def;
  dn_fullcar_default(&def);
  auto named = [&](const char* name, double value, const char* doc) {
    return std::string(what) + "params '" + name + "' = " +
           py::str(py::float_(value)).cast<std::string>() + " (" + doc + "): ";
  };
#define DNPY_REVERT_(type, name, def_, doc)                            \
  if (given.contains(#name)) {                                        \
    dn_fullcar_params trial = p;                                      \
    trial.name = def.name;                                            \
    if (dn_fullcar_check(&trial) >= 0)                                \
      throw py::value_error(named(#name, p.name, doc) + dn_status_str(st)); \
  }
#define DNPY_ALONE_(type, name, def_, doc)                             \
  if (given.contains(#name)) {                                        \
    dn_fullcar_params trial = def;                                    \
    trial.name = p.name;                                              \
    const int s2 = dn_fullcar_check(&trial);                          \
    if (s2 < 0) throw py::value_error(named(#name, p.name, doc) + dn_status_str(s2)); \
  }
  DN_FULLCAR_FIELDS(DNPY_REVERT_)
  DN_FULLCAR_FIELDS(DNPY_ALONE_)
#undef DNPY_REVERT_
#undef DNPY_ALONE_
  throw py::value_error(std::string(what) + "params: " + dn_status_str(st));
}

dn_controller checked_controller(const py::dict& d, const std::string& what) {
  const dn_controller c = controller_from(d);
  dn_vehicle v;
  dn_vehicle_default(&v);
  raise_if_invalid(what.c_str(), py::dict(), v, d, c);
  return c;
}

class PyFullCarModel {
 public:
  struct Deleter {
    void operator()(dn_fullcar_model* m) const { dn_fullcar_model_destroy(m); }
  };
  std::unique_ptr<dn_fullcar_model, Deleter> m;
  std::vector<DamperRef> dampers;  // kept alive (a callback damper's function)
  dn_fullcar_params params{};
  std::array<dn_controller, kN> ctrls{};
  std::vector<double> path_x, path_y;
  int n_features[kN] = {};

  PyFullCarModel(py::handle damper_seq, py::dict p, py::handle controllers, py::handle px,
                 py::handle py_) {
    if (!PySequence_Check(damper_seq.ptr()) || PyUnicode_Check(damper_seq.ptr()))
      throw py::type_error("FullCarModel: dampers must be a sequence of 4 Dampers (FL, FR, RL, RR), got " +
                           describe(damper_seq));
    py::sequence ds = py::reinterpret_borrow<py::sequence>(damper_seq);
    if (ds.size() != kN)
      throw py::value_error("FullCarModel: dampers must be 4 Dampers (FL, FR, RL, RR), got " +
                            std::to_string(ds.size()));
    for (int i = 0; i < kN; ++i) {
      const std::string w = std::string("FullCarModel: dampers[") + std::to_string(i) + "] (" +
                            kCornerNames[i] + ") must be a Damper";
      dampers.push_back(damper_ref(ds[i], w.c_str()));
      n_features[i] = dampers.back().n_features;
    }
    params = fullcar_from(p, "FullCarModel params");
    raise_if_invalid_fullcar("FullCarModel: ", p, params);
    if (controllers.is_none() || PyDict_Check(controllers.ptr())) {
      const py::dict c = controllers.is_none() ? py::dict() : py::reinterpret_borrow<py::dict>(controllers);
      const dn_controller one = checked_controller(c, "FullCarModel: ");
      for (auto& x : ctrls) x = one;
    } else {
      if (!PySequence_Check(controllers.ptr()) || PyUnicode_Check(controllers.ptr()))
        throw py::type_error("FullCarModel: controllers must be a dict (all corners) or 4 dicts, got " +
                             describe(controllers));
      py::sequence cs = py::reinterpret_borrow<py::sequence>(controllers);
      if (cs.size() != kN)
        throw py::value_error("FullCarModel: controllers must be 4 dicts (FL, FR, RL, RR), got " +
                              std::to_string(cs.size()));
      for (int i = 0; i < kN; ++i) {
        py::object ci = cs[i];
        if (!PyDict_Check(ci.ptr()))
          throw py::type_error(std::string("FullCarModel: controllers[") + std::to_string(i) +
                               "] must be a dict, got " + describe(ci));
        ctrls[i] = checked_controller(py::reinterpret_borrow<py::dict>(ci),
                                      std::string("FullCarModel: controllers[") + std::to_string(i) + "] ");
      }
    }
    if (px.is_none() != py_.is_none())
      throw py::value_error("FullCarModel: give both path_x and path_y, or neither");
    if (!px.is_none()) {
      DArray ax = DArray::ensure(px), ay = DArray::ensure(py_);
      if (!ax || !ay) {
        PyErr_Clear();
        throw py::type_error("FullCarModel: path_x and path_y must be arrays of numbers [m]");
      }
      if (ax.ndim() != 1 || ay.ndim() != 1 || ax.size() != ay.size() || ax.size() < 2 ||
          ax.size() > DN_FULLCAR_MAX_PATH)
        throw py::value_error("FullCarModel: path_x and path_y must be 1-D of the same length, 2.." +
                              std::to_string(DN_FULLCAR_MAX_PATH) + " points");
      path_x.assign(ax.data(), ax.data() + ax.size());
      path_y.assign(ay.data(), ay.data() + ay.size());
      for (size_t k = 0; k < path_x.size(); ++k) {
        if (!std::isfinite(path_x[k]) || !std::isfinite(path_y[k]))
          throw py::value_error("FullCarModel: path point " + std::to_string(k) + " is not finite");
        if (k > 0 && !(path_x[k] > path_x[k - 1]))
          throw py::value_error("FullCarModel: path_x must be strictly increasing (point " +
                                std::to_string(k) + ")");
      }
    }
    if (params.steer_mode == DN_STEER_DRIVER && path_x.empty())
      throw py::value_error("FullCarModel: steer_mode 'driver' needs a path (path_x, path_y [m])");
    const dn_damper* dp[kN];
    for (int i = 0; i < kN; ++i) dp[i] = dampers[i].d.get();
    dn_fullcar_model* r = nullptr;
    check(dn_fullcar_model_create(&params, dp, ctrls.data(), path_x.empty() ? nullptr : path_x.data(),
                                  path_y.empty() ? nullptr : path_y.data(), int(path_x.size()), &r),
          "FullCarModel");
    m.reset(r);
  }

  py::list controller_list() const {
    py::list l;
    for (const auto& c : ctrls) l.append(controller_dict(c));
    return l;
  }

  py::array_t<double> mobility() const {
    double K[kN][kN];
    dampnet::corner_mobility(params, K);
    py::array_t<double> k({kN, kN});
    for (int i = 0; i < kN; ++i)
      for (int j = 0; j < kN; ++j) k.mutable_at(i, j) = K[i][j];
    return k;
  }
};

// The report of one step as a dict: corner quantities as 4-arrays, vehicle ones as floats.
py::dict report_dict(const dn_fullcar_out& o, int status) {
  py::dict d;
#define DNPY_CORNER_(name, doc) \
  d[#name] = py::array_t<double>(kN, o.name);
  DN_FULLCAR_OUT_CORNER_LIST(DNPY_CORNER_)
#undef DNPY_CORNER_
#define DNPY_SCALAR_(name, doc) d[#name] = o.name;
  DN_FULLCAR_OUT_LIST(DNPY_SCALAR_)
#undef DNPY_SCALAR_
  d["clamped_mask"] = py::array_t<uint32_t>(kN, o.clamped_mask);
  d["status"] = status;
  return d;
}

// Four numbers from a sequence/array (road, rate, controls).
std::array<double, kN> four(py::handle h, const char* what) {
  DArray a = DArray::ensure(h);
  if (!a) {
    PyErr_Clear();
    throw py::type_error(std::string(what) + ": expected 4 numbers (FL, FR, RL, RR), got " + describe(h));
  }
  if (a.size() != kN)
    throw py::value_error(std::string(what) + ": expected 4 values (FL, FR, RL, RR), got " +
                          std::to_string(a.size()));
  std::array<double, kN> r{};
  for (int i = 0; i < kN; ++i) r[i] = a.data()[i];
  return r;
}

class PyFullCar {
 public:
  struct Deleter {
    void operator()(dn_fullcar_data* d) const { dn_fullcar_data_destroy(d); }
  };
  std::shared_ptr<PyFullCarModel> model;
  std::unique_ptr<dn_fullcar_data, Deleter> d;
  mutable std::atomic<bool> busy{false};

  explicit PyFullCar(std::shared_ptr<PyFullCarModel> m) : model(std::move(m)) {
    dn_fullcar_data* r = nullptr;
    check(dn_fullcar_data_create(model->m.get(), &r), "FullCar");
    d.reset(r);
  }

  void reset() {
    BusyGuard guard(busy, "FullCar.reset", kFullCarContract);
    dn_fullcar_reset(model->m.get(), d.get());
  }

  py::array_t<double> get_state() const {
    py::array_t<double> s(DN_FULLCAR_STATE_SIZE);
    BusyGuard guard(busy, "FullCar.state", kFullCarContract);
    dn_fullcar_get_state(d.get(), s.mutable_data());
    return s;
  }
  void set_state(DArray s) {
    if (s.size() != DN_FULLCAR_STATE_SIZE)
      throw py::value_error("FullCar.state: expected " + std::to_string(DN_FULLCAR_STATE_SIZE) +
                            " values (FULLCAR_STATE_NAMES)");
    BusyGuard guard(busy, "FullCar.state", kFullCarContract);
    check(dn_fullcar_set_state(d.get(), s.data()), "FullCar.state");
  }

  py::dict report(py::handle z_r, py::handle v_r, double steer, py::handle u, bool advance) {
    dn_fullcar_input in{};
    if (advance) {
      const auto zr = four(z_r, "FullCar.step z_r [m]"), vr = four(v_r, "FullCar.step v_r [m/s]");
      for (int i = 0; i < kN; ++i) in.z_r[i] = zr[i], in.v_r[i] = vr[i];
    }
    in.steer = steer;
    if (!u.is_none()) {
      const auto uu = four(u, "FullCar u [V]");
      for (int i = 0; i < kN; ++i) in.u[i] = uu[i];
    }
    dn_fullcar_out o{};
    int st;
    {
      BusyGuard guard(busy, advance ? "FullCar.step" : "FullCar.forward", kFullCarContract);
      CallbackRun run;
      st = advance ? dn_fullcar_step(model->m.get(), d.get(), &in, &o)
                   : dn_fullcar_forward(model->m.get(), d.get(), &in, &o);
      run.raise_pending();
    }
    check(st, advance ? "FullCar.step" : "FullCar.forward");
    return report_dict(o, st);
  }

  py::dict step(py::handle z_r, py::handle v_r, double steer, py::handle u) {
    return report(z_r, v_r, steer, u, true);
  }
  py::dict forward(double steer, py::handle u) { return report(py::none(), py::none(), steer, u, false); }

  // A whole run in C++ (GIL released): row k of road / road_rate is the road under the four
  // wheels at t = k dt; step k takes row k + 1 as its end-of-step input, and the last row
  // is reported by forward() (as Loop.simulate).
  py::dict simulate(py::handle road_h, py::handle rate_h, py::handle steer_h, py::handle u_h,
                    bool reset_first) {
    DArray road = DArray::ensure(road_h), rate = DArray::ensure(rate_h);
    if (!road || !rate) {
      PyErr_Clear();
      throw py::type_error("FullCar.simulate: road and road_rate must be arrays of numbers [n, 4]");
    }
    if (road.ndim() != 2 || road.shape(1) != kN || rate.ndim() != 2 || rate.shape(1) != kN ||
        road.shape(0) != rate.shape(0) || road.shape(0) < 1)
      throw py::value_error("FullCar.simulate: road [m] and road_rate [m/s] must both be [n, 4] "
                            "(FL, FR, RL, RR), n >= 1");
    const py::ssize_t n = road.shape(0);
    DArray steer, u;
    if (!steer_h.is_none()) {
      steer = DArray::ensure(steer_h);
      if (!steer) {
        PyErr_Clear();
        throw py::type_error("FullCar.simulate: steer must be an array of numbers [rad]");
      }
      if (steer.ndim() != 1 || steer.size() != n)
        throw py::value_error("FullCar.simulate: steer [rad] must be 1-D with one value per road row");
    }
    if (!u_h.is_none()) {
      u = DArray::ensure(u_h);
      if (!u) {
        PyErr_Clear();
        throw py::type_error("FullCar.simulate: u must be an array of numbers [V]");
      }
      if (u.ndim() != 2 || u.shape(0) != n || u.shape(1) != kN)
        throw py::value_error("FullCar.simulate: u [V] must be [n, 4], one row per road row");
    }
    py::array_t<double> state({n, py::ssize_t(DN_FULLCAR_STATE_SIZE)});
    py::array_t<int32_t> status(n);
    std::vector<py::array_t<double>> corner_arrays, scalar_arrays;
#define DNPY_ALLOC_C_(name, doc) corner_arrays.emplace_back(std::vector<py::ssize_t>{n, kN});
#define DNPY_ALLOC_S_(name, doc) scalar_arrays.emplace_back(n);
    DN_FULLCAR_OUT_CORNER_LIST(DNPY_ALLOC_C_)
    DN_FULLCAR_OUT_LIST(DNPY_ALLOC_S_)
#undef DNPY_ALLOC_C_
#undef DNPY_ALLOC_S_
    py::array_t<uint32_t> masks({n, py::ssize_t(kN)});
    std::vector<double*> cp, sp;
    for (auto& a : corner_arrays) cp.push_back(a.mutable_data());
    for (auto& a : scalar_arrays) sp.push_back(a.mutable_data());
    double* S = state.mutable_data();
    int32_t* ST = status.mutable_data();
    uint32_t* MK = masks.mutable_data();
    const double *R = road.data(), *RR = rate.data();
    // a default DArray is an empty array, not a null handle: whether given is the argument's
    const double* SS = steer_h.is_none() ? nullptr : steer.data();
    const double* UU = u_h.is_none() ? nullptr : u.data();
    const dn_fullcar_model* m = model->m.get();
    dn_fullcar_data* dd = d.get();
    py::ssize_t fail_at = -1;
    int fail_status = 0;
    BusyGuard guard(busy, "FullCar.simulate", kFullCarContract);
    CallbackRun run;
    {
      py::gil_scoped_release release;
      if (reset_first) dn_fullcar_reset(m, dd);
      double s[DN_FULLCAR_STATE_SIZE];
      dn_fullcar_get_state(dd, s);
      for (int i = 0; i < kN; ++i) {
        s[dampnet::fc_corner(i, dampnet::FCC_z_r)] = R[i];
        s[dampnet::fc_corner(i, dampnet::FCC_v_r)] = RR[i];
      }
      fail_status = dn_fullcar_set_state(dd, s);
      if (fail_status < 0) fail_at = 0;
      for (py::ssize_t k = 0; k < n && fail_at < 0; ++k) {
        dn_fullcar_get_state(dd, S + k * DN_FULLCAR_STATE_SIZE);
        dn_fullcar_input in{};
        in.steer = SS ? SS[k] : 0.0;
        for (int i = 0; i < kN; ++i) in.u[i] = UU ? UU[k * kN + i] : 0.0;
        dn_fullcar_out o{};
        int st;
        if (k + 1 < n) {
          for (int i = 0; i < kN; ++i) in.z_r[i] = R[(k + 1) * kN + i], in.v_r[i] = RR[(k + 1) * kN + i];
          st = dn_fullcar_step(m, dd, &in, &o);
        } else {
          st = dn_fullcar_forward(m, dd, &in, &o);
        }
        ST[k] = st;
        if (st < 0) {
          fail_at = k;
          fail_status = st;
          break;
        }
        int c = 0;
#define DNPY_WRITE_C_(name, doc) \
  for (int i = 0; i < kN; ++i) cp[c][k * kN + i] = o.name[i]; \
  ++c;
        DN_FULLCAR_OUT_CORNER_LIST(DNPY_WRITE_C_)
#undef DNPY_WRITE_C_
        c = 0;
#define DNPY_WRITE_S_(name, doc) sp[c++][k] = o.name;
        DN_FULLCAR_OUT_LIST(DNPY_WRITE_S_)
#undef DNPY_WRITE_S_
        for (int i = 0; i < kN; ++i) MK[k * kN + i] = o.clamped_mask[i];
      }
    }
    run.raise_pending();
    if (fail_at >= 0)
      throw py::value_error("FullCar.simulate: row " + std::to_string(fail_at) + ": " +
                            dn_status_str(fail_status));
    py::dict res;
    res["state"] = state;
    res["status"] = status;
    int c = 0;
#define DNPY_PUT_C_(name, doc) res[#name] = corner_arrays[c++];
    DN_FULLCAR_OUT_CORNER_LIST(DNPY_PUT_C_)
#undef DNPY_PUT_C_
    c = 0;
#define DNPY_PUT_S_(name, doc) res[#name] = scalar_arrays[c++];
    DN_FULLCAR_OUT_LIST(DNPY_PUT_S_)
#undef DNPY_PUT_S_
    res["clamped_mask"] = masks;
    return res;
  }

  int64_t damper_evals() const {
    BusyGuard guard(busy, "FullCar.damper_evals", kFullCarContract);
    return dn_fullcar_damper_evals(d.get());
  }
};

}  // namespace

void bind_fullcar(py::module_& mod) {
  {
    py::dict fields;
#define DNPY_DOC_(type, name, def, doc) fields[#name] = py::make_tuple(static_cast<type>(def), doc);
    DN_FULLCAR_FIELDS(DNPY_DOC_)
#undef DNPY_DOC_
    mod.attr("FULLCAR_FIELDS") = fields;
    py::list names;
#define DNPY_SNAME_(i, name, doc) names.append(#name);
    DN_FULLCAR_STATE_LIST(DNPY_SNAME_)
#undef DNPY_SNAME_
    for (int i = 0; i < kN; ++i) {
#define DNPY_CNAME_(k, name, doc) names.append(std::string(#name) + "_" + kCornerNames[i]);
      DN_FULLCAR_CORNER_STATE_LIST(DNPY_CNAME_)
#undef DNPY_CNAME_
#define DNPY_DSNAME_(id, name, unit, dyn, source, param, doc) names.append(std::string(#name) + "_" + kCornerNames[i]);
      DN_DAMPER_STATE_LIST(DNPY_DSNAME_)  // the corner damper's block
#undef DNPY_DSNAME_
    }
    mod.attr("FULLCAR_STATE_NAMES") = py::tuple(names);
    py::dict corner_out, out;
#define DNPY_ODOC_C_(name, doc) corner_out[#name] = doc;
#define DNPY_ODOC_S_(name, doc) out[#name] = doc;
    DN_FULLCAR_OUT_CORNER_LIST(DNPY_ODOC_C_)
    DN_FULLCAR_OUT_LIST(DNPY_ODOC_S_)
#undef DNPY_ODOC_C_
#undef DNPY_ODOC_S_
    mod.attr("FULLCAR_OUT_CORNER_FIELDS") = corner_out;
    mod.attr("FULLCAR_OUT_FIELDS") = out;
    py::tuple corners(kN);
    for (int i = 0; i < kN; ++i) corners[i] = kCornerNames[i];
    mod.attr("FULLCAR_CORNERS") = corners;
    py::dict tyres, steers;
#define DNPY_EROW_(id, value, name, doc) target[name] = py::make_tuple(int(value), doc);
    {
      py::dict& target = tyres;
      DN_TYRE_MODEL_LIST(DNPY_EROW_)
    }
    {
      py::dict& target = steers;
      DN_STEER_MODE_LIST(DNPY_EROW_)
    }
#undef DNPY_EROW_
    mod.attr("TYRE_MODELS") = tyres;
    mod.attr("STEER_MODES") = steers;
  }
  mod.def("check_fullcar", [](py::dict params) {
    const dn_fullcar_params p = fullcar_from(params, "params");
    raise_if_invalid_fullcar("", params, p);
  }, py::arg("params"),
     "Validate full-car parameters (FULLCAR_FIELDS) as FullCarModel does: None, or ValueError / "
     "TypeError naming the field and its valid range or names.");

  refuse_reinit(py::class_<PyFullCarModel, std::shared_ptr<PyFullCarModel>>(
      mod, "FullCarModel",
      "The full vehicle's parameters, four dampers (FL, FR, RL, RR), four controllers and the "
      "driver's path (constant): immutable, may drive FullCars in many threads at once.")
      .def(py::init([](py::handle dampers, py::dict params, py::handle controllers, py::handle path_x,
                       py::handle path_y) {
             return std::make_shared<PyFullCarModel>(dampers, params, controllers, path_x, path_y);
           }),
           py::arg("dampers"), py::arg("params") = py::dict(), py::arg("controllers") = py::none(),
           py::arg("path_x") = py::none(), py::arg("path_y") = py::none())
      .def_property_readonly("params", [](py::handle m) { return fullcar_dict(constructed<PyFullCarModel>(m).params); })
      .def_property_readonly("controllers", method(&PyFullCarModel::controller_list))
      .def_property_readonly("corner_mobility", method(&PyFullCarModel::mobility),
                             "K [1/kg]: the corners' relative accelerations per damper force (a = a_free - K (F - f_static))."));

  refuse_reinit(py::class_<PyFullCar>(mod, "FullCar",
                        "A full vehicle's state (mutable) for a FullCarModel. Not shareable: one call at a "
                        "time (a second concurrent call raises RuntimeError); one FullCar per thread.")
      .def(py::init([](py::handle model) {
             return std::make_unique<PyFullCar>(shared<PyFullCarModel>(model, "FullCar: model must be a FullCarModel"));
           }),
           py::arg("model"))
      .def("reset", method(&PyFullCar::reset))
      .def_property("state", method(&PyFullCar::get_state), method(&PyFullCar::set_state),
                    "Flat state (FULLCAR_STATE_NAMES).")
      .def("step", method(&PyFullCar::step), py::arg("z_r"), py::arg("v_r"), py::arg("steer") = 0.0,
           py::arg("u") = py::none(),
           "One step: road [m] and rate [m/s] under the 4 wheels at the end of the step, steer [rad] "
           "(open loop), u [V] for external controllers. Returns the report at the step start.")
      .def("forward", method(&PyFullCar::forward), py::arg("steer") = 0.0, py::arg("u") = py::none(),
           "The report without advancing.")
      .def("simulate", method(&PyFullCar::simulate), py::arg("road"), py::arg("road_rate"),
           py::arg("steer") = py::none(), py::arg("u") = py::none(), py::arg("reset") = true,
           "Run roads [n, 4] in C++ (GIL released) -> dict of arrays: state [n, S], status [n], "
           "the report's corner fields [n, 4] and vehicle fields [n].")
      .def_property_readonly("model", [](py::handle c) { return constructed<PyFullCar>(c).model; })
      .def_property_readonly("damper_evals", method(&PyFullCar::damper_evals)));
}

}  // namespace dnpy
