"""``python -m bench.load [--quick] [--out DIR]`` (needs ``redis-server``)."""

import sys

from bench.load.main import BENCHMARK

sys.exit(BENCHMARK.main())
