/* The generated header included from two C translation units of one program. */
#include "dampnet/dampnet.h"
#include "dn_model_default.h"

int tu_a_inputs(void) { return DN_MODEL_DEFAULT_N_INPUTS; }
double tu_a_first_weight(void) { return dn_model_default_w1[0]; }
