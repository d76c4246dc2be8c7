"""Test and benchmark data: synthetic sequences with known ground truth.

Not used by the tracker; :mod:`engine.testing.synthetic` renders seeded
sequences (frames and amodal masks) of named conditions for the test suite
and ``bench/``; :mod:`engine.testing.crowd` a scene of several moving objects,
some crossing each other, with a mask per object.
"""
