// Version and status strings of the C ABI.
#include "dampnet/dampnet.h"

#define DN_STR2_(x) #x
#define DN_STR_(x) DN_STR2_(x)

extern "C" {

int dn_version(void) { return DN_VERSION_HEADER; }

const char* dn_version_string(void) {
  return DN_STR_(DN_VERSION_MAJOR) "." DN_STR_(DN_VERSION_MINOR) "." DN_STR_(DN_VERSION_PATCH);
}

const char* dn_status_str(int status) {
  switch (status) {
#define DN_STATUS_CASE_(name, value, text) \
  case value:                              \
    return #name ": " text;
    DN_STATUS_LIST(DN_STATUS_CASE_)
#undef DN_STATUS_CASE_
    case DN_W_SATURATED | DN_W_NONFINITE_INPUT:
      return "DN_W_SATURATED|DN_W_NONFINITE_INPUT: an input was clamped to its saturation "
             "limits and a NaN input was replaced by the centre of its range";
    case DN_W_SATURATED | DN_W_ACCEL_UNCONVERGED:
      return "DN_W_SATURATED|DN_W_ACCEL_UNCONVERGED: an input was clamped to its saturation "
             "limits and the implicit acceleration feature did not converge";
    case DN_W_NONFINITE_INPUT | DN_W_ACCEL_UNCONVERGED:
      return "DN_W_NONFINITE_INPUT|DN_W_ACCEL_UNCONVERGED: a NaN input was replaced by the "
             "centre of its range and the implicit acceleration feature did not converge";
    case DN_W_SATURATED | DN_W_NONFINITE_INPUT | DN_W_ACCEL_UNCONVERGED:
      return "DN_W_SATURATED|DN_W_NONFINITE_INPUT|DN_W_ACCEL_UNCONVERGED: an input was clamped, "
             "a NaN input was replaced, and the implicit acceleration feature did not converge";
    default:
      return "unknown dampnet status code";
  }
}

}  // extern "C"
