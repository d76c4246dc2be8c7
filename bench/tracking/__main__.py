"""``python -m bench.tracking [--quick] [--out DIR] [--sets ...] [--cv OPTION=V1,V2 ...]``."""

import os
import sys

# One thread everywhere, for fair timings: set before numpy / OpenCV / numba load.  The
# worker processes (spawned: they import this module as ``__mp_main__``) inherit them.
for _variable in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMBA_NUM_THREADS",
):
    os.environ[_variable] = "1"

if __name__ == "__main__":
    from bench.tracking.main import BENCHMARK

    sys.exit(BENCHMARK.main())
