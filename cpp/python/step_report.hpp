// What Loop.step returns (step_report.cpp): the step's report as read-only attributes, and
// also as a read-only mapping with the same keys (r["force"], r.get, r.keys(), dict(r)), so
// code that reads the former dict keeps working; it is not a dict (==, json, pickle, copy
// need dict(r)). Its keys are STEP_OUTPUT_FIELDS: dn_loop_out's quantities
// (DN_LOOP_OUT_LIST), then features, clamped_mask and status.
#pragma once

#include <pybind11/pybind11.h>

#include "dampnet/dampnet.h"

namespace dnpy {

struct StepReport {
  dn_loop_out o;
  int status;
};

// A new, uninitialised StepReport object; *r points at its struct, for the loop to fill.
pybind11::object new_step_report(StepReport** r);

// {key: doc with unit} of every key, in order (_core.STEP_OUTPUT_FIELDS).
pybind11::dict step_output_fields();

// The report as a plain dict (StepReport.to_dict).
pybind11::dict step_report_dict(const dn_loop_out& o, int status);

}  // namespace dnpy
