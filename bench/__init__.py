"""The project's benchmarks, one sub-package per family; results land in ``bench/results/``.

- :mod:`bench.solvers`: the paper's section IV (errors against DMMA, time per
  deformation) and the solver speed goals (``make bench-solvers``);
- :mod:`bench.tracking`: contour trackers on DAVIS-2016 (the thirty training
  sequences and the five validation ones) and synthetic sequences
  (``make bench-tracking``), and the cross-validation of efdm's options on
  folds of the training sequences (``--cv``);
- :mod:`bench.serving`: a real ``efdm serve`` against ``engine.Tracker``
  in-process (``make bench-service``);
- :mod:`bench.load`: many concurrent WebSocket sessions on 1 and 2 replicas
  sharing a Redis (``make bench-load``);
- :mod:`bench.common`: what they share (configuration and command line, the
  run skeleton, logging, results, goal lines, machine info, timing, processes).

Run a family from the repository root as ``python -m bench.<family>``;
``--quick`` runs a reduced set for smoke tests, ``--out DIR`` writes elsewhere.
Nothing here is imported on ``import bench``: the tracking family pins its
thread counts before numpy loads.
"""
