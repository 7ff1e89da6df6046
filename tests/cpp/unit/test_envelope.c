/* The training envelope's check through the C ABI (dampnet.h "Training envelope"): cells by the
 * header's definition on a hand-made grid (the edges, the last cell at x = hi, NaN and Inf),
 * the refusals of bad descriptions with *out = NULL, create and init in caller memory alike.
 * C99. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "dampnet/dampnet.h"

#include "expect.h"

static void mark(uint32_t* cells, int pair, int ci, int cj) {
  const int bit = ci * DN_ENVELOPE_CELLS + cj;
  cells[pair * DN_ENVELOPE_PAIR_WORDS + bit / 32] |= 1u << (bit % 32);
}

static uint32_t flags_of(const dn_envelope* e, double x0, double x1, double x2) {
  const double x[3] = {x0, x1, x2};
  uint32_t f = 99;
  EXPECT(dn_envelope_check(e, x, &f) == DN_OK);
  return f;
}

int main(void) {
  /* three inputs on [0, 1], [-2, 2], [0, 5]: pairs (0,1), (0,2), (1,2) */
  const double lo[3] = {0.0, -2.0, 0.0}, hi[3] = {1.0, 2.0, 5.0};
  uint32_t cells[3 * DN_ENVELOPE_PAIR_WORDS];
  memset(cells, 0, sizeof cells);
  /* the point (0.5, 0, 2.5): cells 16, 16, 16 in every pair */
  mark(cells, 0, 16, 16);
  mark(cells, 1, 16, 16);
  mark(cells, 2, 16, 16);
  /* the corner (1, 2, 5): the last cell (31) of each input */
  mark(cells, 0, 31, 31);
  mark(cells, 1, 31, 31);
  mark(cells, 2, 31, 31);
  const dn_envelope_desc desc = {3, lo, hi, cells};
  dn_envelope* e = NULL;
  EXPECT(dn_envelope_create(&desc, &e) == DN_OK && e != NULL);
  EXPECT(dn_envelope_n_inputs(e) == 3);
  EXPECT(flags_of(e, 0.5, 0.0, 2.5) == 0);
  EXPECT(flags_of(e, 0.5 + 0.99 / 32, 0.0, 2.5) == 0);    /* still cell 16 */
  EXPECT(flags_of(e, 0.5 + 1.01 / 32, 0.0, 2.5) == DN_ENV_OUTSIDE_JOINT); /* cell 17 */
  EXPECT(flags_of(e, 1.0, 2.0, 5.0) == 0);                  /* x = hi: the last cell */
  EXPECT(flags_of(e, 0.5, 0.0, 5.0) == DN_ENV_OUTSIDE_JOINT);
  EXPECT(flags_of(e, 1.0 + 1e-12, 2.0, 5.0) == DN_ENV_OUTSIDE_RANGE); /* only the in-range pair (1,2) left */
  EXPECT(flags_of(e, 1.5, 0.0, 5.0) == (DN_ENV_OUTSIDE_RANGE | DN_ENV_OUTSIDE_JOINT));
  EXPECT(flags_of(e, NAN, 0.0, 2.5) == DN_ENV_OUTSIDE_RANGE);
  EXPECT(flags_of(e, INFINITY, -INFINITY, 2.5) == DN_ENV_OUTSIDE_RANGE);
  {
    const float xf[3] = {0.5f, 0.0f, 2.5f};
    uint32_t f = 99;
    EXPECT(dn_envelope_check_f(e, xf, &f) == DN_OK && f == 0);
  }
  {
    const double x[3] = {0.5, 0.0, 2.5};
    uint32_t f = 0;
    EXPECT(dn_envelope_check(NULL, x, &f) == DN_E_NULL);
    EXPECT(dn_envelope_check(e, NULL, &f) == DN_E_NULL);
    EXPECT(dn_envelope_check(e, x, NULL) == DN_E_NULL);
  }

  /* init in caller memory: the same flags as create */
  {
    void* raw = malloc(dn_envelope_size() + DN_STORAGE_ALIGN);
    unsigned char* mem = (unsigned char*)raw + (DN_STORAGE_ALIGN - (size_t)((uintptr_t)raw % DN_STORAGE_ALIGN)) %
                                                   DN_STORAGE_ALIGN;
    dn_envelope* m = (dn_envelope*)&m;
    EXPECT(dn_envelope_init(&desc, mem, dn_envelope_size() - 1, &m) == DN_E_SIZE && m == NULL);
    EXPECT(dn_envelope_init(&desc, mem, dn_envelope_size(), &m) == DN_OK && m != NULL);
    for (int k = 0; k < 200; ++k) {
      const double a = -0.2 + 1.4 * k / 199.0, b = 2.0 * sin(k), c = 2.5 + 3.0 * cos(0.3 * k);
      EXPECT(flags_of(m, a, b, c) == flags_of(e, a, b, c));
    }
    free(raw);
  }

  /* refusals: *out stays NULL */
  {
    dn_envelope* bad = (dn_envelope*)&bad;
    dn_envelope_desc d = desc;
    d.n_inputs = 0;
    EXPECT(dn_envelope_create(&d, &bad) == DN_E_SIZE && bad == NULL);
    d.n_inputs = DN_MAX_INPUTS + 1;
    EXPECT(dn_envelope_create(&d, &bad) == DN_E_SIZE && bad == NULL);
    d = desc;
    d.cells = NULL;
    EXPECT(dn_envelope_create(&d, &bad) == DN_E_NULL && bad == NULL);
    d.n_inputs = 1; /* one input: no pairs, no cells needed */
    EXPECT(dn_envelope_create(&d, &bad) == DN_OK && bad != NULL);
    EXPECT(flags_of(bad, 0.3, 0, 0) == 0 && flags_of(bad, -0.1, 0, 0) == DN_ENV_OUTSIDE_RANGE);
    dn_envelope_destroy(bad);
    const double lo2[3] = {0.0, 2.5, 0.0}, nan_lo[3] = {NAN, -2.0, 0.0}, huge_lo[3] = {-1e308, -2.0, 0.0},
                 huge_hi[3] = {1e308, 2.0, 5.0};
    d = desc;
    d.lo = lo2; /* hi < lo for input 1 */
    EXPECT(dn_envelope_create(&d, &bad) == DN_E_PARAM && bad == NULL);
    d.lo = nan_lo;
    EXPECT(dn_envelope_create(&d, &bad) == DN_E_NONFINITE_PARAM && bad == NULL);
    d.lo = huge_lo; /* a width beyond double: refused, not a NaN cell index later */
    d.hi = huge_hi;
    EXPECT(dn_envelope_create(&d, &bad) == DN_E_PARAM && bad == NULL);
    EXPECT(dn_envelope_create(NULL, &bad) == DN_E_NULL && bad == NULL);
    /* a constant input (hi = lo, a model trained on a constant column) or a width too small to
     * divide (1e-310) is one cell: inside at exactly its value, outside off it */
    {
      const double c_lo[3] = {0.0, 1.0, 0.0}, c_hi[3] = {1.0, 1.0, 1e-310};
      uint32_t c_cells[3 * DN_ENVELOPE_PAIR_WORDS];
      memset(c_cells, 0, sizeof c_cells);
      mark(c_cells, 0, 16, 0); /* (x0 in cell 16, x1 = 1) */
      mark(c_cells, 1, 16, 0);
      mark(c_cells, 2, 0, 0);
      const dn_envelope_desc cd = {3, c_lo, c_hi, c_cells};
      dn_envelope* c = NULL;
      EXPECT(dn_envelope_create(&cd, &c) == DN_OK && c != NULL);
      EXPECT(flags_of(c, 0.51, 1.0, 0.0) == 0);
      EXPECT(flags_of(c, 0.51, 1.0, 1e-310) == 0);
      EXPECT(flags_of(c, 0.51, 1.0 + 1e-9, 0.0) == DN_ENV_OUTSIDE_RANGE);
      EXPECT(flags_of(c, 0.9, 1.0, 0.0) == DN_ENV_OUTSIDE_JOINT);
      dn_envelope_destroy(c);
    }
    EXPECT(dn_envelope_create(&desc, NULL) == DN_E_NULL);
    EXPECT(dn_envelope_n_inputs(NULL) == DN_E_NULL);
    dn_envelope_destroy(NULL);
  }
  dn_envelope_destroy(e);
  if (failures) return 1;
  printf("test_envelope: all checks passed (dn_envelope %zu bytes)\n", dn_envelope_size());
  return 0;
}
