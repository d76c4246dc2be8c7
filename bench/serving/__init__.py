"""The service overhead benchmark: ``python -m bench.serving``; see :mod:`.main`.

Named ``serving`` so that it does not shadow the ``service`` package it measures.
"""
