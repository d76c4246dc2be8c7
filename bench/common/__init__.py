"""What every benchmark family shares.

- :mod:`~bench.common.config`: the ``Config`` base and the ``--quick`` / ``--out`` command line;
- :mod:`~bench.common.benchmark`: the run skeleton every family's ``main`` is;
- :mod:`~bench.common.log`: progress lines;
- :mod:`~bench.common.output`: the result files (markdown and JSON);
- :mod:`~bench.common.report`: number formatting, markdown tables, goal lines;
- :mod:`~bench.common.machine`: what machine a run was on;
- :mod:`~bench.common.timing`: warm-up, calibrated repeats, medians;
- :mod:`~bench.common.processes`: ports, subprocesses, CPU time;
- :mod:`~bench.common.data`: the DAVIS-2016 sequences and the synthetic sequences;
- :mod:`~bench.common.study`: the command line of a one-off study over the DAVIS sets.

Importing this package loads nothing but :mod:`pathlib`.
"""

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
"""The repository root (subprocesses run there)."""
RESULTS = REPO / "bench" / "results"
"""Where the result files go unless ``--out`` says otherwise."""
