"""``python -m bench.solvers [--quick] [--out DIR]``."""

import sys

from bench.solvers.main import BENCHMARK

sys.exit(BENCHMARK.main())
