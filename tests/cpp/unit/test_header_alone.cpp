// test_header_alone.c compiled as C++17 (each public header alone, first; see there).
#include "test_header_alone.c"
