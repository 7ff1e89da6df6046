"""cffi declarations of the C ABI (dampnet.h), shared by the tests that load the shared library.

cffi cannot parse the header's macros, so the declarations the tests use are written out
here once; test_cdefs_match_the_header checks the struct fields against dampnet.h's (dn_types.h)."""

MLP_CDEF = """
typedef struct dn_mlp_desc {
  int n_inputs; int n_hidden1; int n_hidden2; int activation;
  const double* w1; const double* b1; const double* w2; const double* b2;
  const double* w_out; const double* b_out; const double* in_offset; const double* in_gain;
  double in_ymin; double out_offset; double out_gain; double out_ymin;
  const double* sat_lo; const double* sat_hi;
} dn_mlp_desc;
typedef struct dn_mlp dn_mlp;
"""
