// Version and status strings of the C ABI.
#include <cstring>

#include "dampnet/dampnet.h"

#define DN_STR2_(x) #x
#define DN_STR_(x) DN_STR2_(x)

namespace {

// The warnings, in bit order: name and text of each DN_W_* flag.
struct Warning {
  int bit;
  const char* name;
  const char* text;
};
#define DN_WARNING_ROW_(name, value, text) {value, #name, text},
constexpr Warning kStatuses[] = {DN_STATUS_LIST(DN_WARNING_ROW_)};
#undef DN_WARNING_ROW_

constexpr int warning_bits() {
  int all = 0;
  for (const Warning& w : kStatuses)
    if (w.bit > 0) all |= w.bit;
  return all;
}
constexpr int kAllWarnings = warning_bits();
static_assert((kAllWarnings & (kAllWarnings + 1)) == 0, "warnings are the low bits 1, 2, 4, ...");

// An OR of several warnings: "NAME1|NAME2: text1; text2", one static buffer per combination,
// filled once (a function-local static: thread-safe initialisation, no heap afterwards).
constexpr int kCombinedLen = 1024;
// Every warning's name and text together, with separators, fit: a new DN_W_ fails the build
// here rather than being cut off silently by strncat.
#define DN_WARNING_LEN_(id, value, text) +((value) > 0 ? sizeof(#id) + sizeof(text) + 2 : 0)
static_assert(3 DN_STATUS_LIST(DN_WARNING_LEN_) < kCombinedLen, "raise kCombinedLen");
#undef DN_WARNING_LEN_
struct Combined {
  char text[kAllWarnings + 1][kCombinedLen];
  Combined() {
    for (int s = 0; s <= kAllWarnings; ++s) {
      char* out = text[s];
      out[0] = '\0';
      auto append = [&](const char* part) {
        std::strncat(out, part, kCombinedLen - 1 - std::strlen(out));
      };
      bool first = true;
      for (const Warning& w : kStatuses)
        if (w.bit > 0 && (s & w.bit)) append(first ? "" : "|"), append(w.name), first = false;
      append(": ");
      first = true;
      for (const Warning& w : kStatuses)
        if (w.bit > 0 && (s & w.bit)) append(first ? "" : "; "), append(w.text), first = false;
    }
  }
};

}  // namespace

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
    default:
      break;
  }
  if (status > 0 && (status & ~kAllWarnings) == 0) {
    static const Combined combined;
    return combined.text[status];
  }
  return "unknown dampnet status code";
}

}  // extern "C"
