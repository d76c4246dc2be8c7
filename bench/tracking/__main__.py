"""``python -m bench.tracking [--quick] [--out DIR] [--sequences a,b] [--trackers x,y]``."""

import os
import sys

# One thread everywhere, for fair timings: set before numpy / OpenCV / numba load.
for _variable in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMBA_NUM_THREADS",
):
    os.environ[_variable] = "1"

from bench.tracking.main import BENCHMARK  # noqa: E402

sys.exit(BENCHMARK.main())
