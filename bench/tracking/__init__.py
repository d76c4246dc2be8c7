"""The tracking benchmark: ``python -m bench.tracking``; see :mod:`.main`.

Imports nothing: ``__main__`` pins the thread counts before numpy, OpenCV and
numba load, and other families import :mod:`bench.tracking` modules without
being pinned.
"""
