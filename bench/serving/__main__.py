"""``python -m bench.serving [--quick] [--out DIR]``: ``service.md`` and ``service.json``."""

import sys

from bench.serving.main import BENCHMARK

sys.exit(BENCHMARK.main())
