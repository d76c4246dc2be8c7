"""The load benchmark (concurrent sessions, 1 and 2 replicas, Redis): ``python -m bench.load``.

See :mod:`.main`; it reuses the service benchmark's server harness, client
and measurements (:mod:`bench.serving`).
"""
