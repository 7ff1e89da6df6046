"""The hot-path code footprint of dn_fullcar_step and dn_loop_step (bytes of the functions
their static call graph reaches, from the built libdampnet.so's symbols and disassembly):
a thin front for dampnet.latency.footprint, whose docstring says what is counted.

    python bench/footprint.py [LIBRARY] [--entry SYMBOL ...] [--json FILE]
    python bench/footprint.py [LIBRARY] --dynamic [--config NAME ...] [--steps N] [--json FILE]

--dynamic (valgrind callgrind) sums the symbol sizes of the functions the full car's benchmark
configurations actually call: issue 30's "<= 16 KB" is judged on that number.
"""

import sys

from dampnet.latency.footprint import main

if __name__ == "__main__":
    sys.exit(main())
