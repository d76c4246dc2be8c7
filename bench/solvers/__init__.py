"""The solver benchmark (the paper's section IV): ``python -m bench.solvers``; see :mod:`.main`."""
