"""What the solver benchmark measures: sizes, methods, budgets, the paper's numbers, the goals."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from bench.common.config import Config as BaseConfig

A_MAIN = 10.0
"""Stiffness ``a = k/m`` of the timings, the goals and the main error panel."""

EFDMT_TOL = 1e-8
"""Tolerance of the second EFDMT variant of the error study."""

PAPER_ERROR_PCT = {"efdm": 0.0, "efdmt": 0.00000314, "dmmat": 0.00293462}
"""The paper's average errors against DMMA (section IV, fig. 2), in percent."""

TIMED_METHODS = ("dmma", "dmmat", "efdm", "efdmt", "exact", "fft")
ERROR_METHODS = ("efdm", "efdmt", "efdmt_tol", "dmmat", "exact", "fft", "literal")
ERROR_LABELS = {
    "efdm": "EFDM",
    "efdmt": "EFDMT (paper M)",
    "efdmt_tol": f"EFDMT (tol={EFDMT_TOL:g})",
    "dmmat": "DMMAT (25 %)",
    "exact": "exact",
    "fft": "numpy FFT",
    "literal": "literal eq. 18",
}

LITERAL_CASES = ((101, 10.0), (101, 100.0), (500, 10.0), (541, 10.0), (1000, 10.0), (2000, 10.0))
"""(N, a) at which the paper's eq. 18 as printed is compared with DMMA."""

LITERAL_STIFFNESSES = (1.0, 10.0, 100.0)
"""a at which the first N where eq. 18 as printed breaks down is searched for."""

LITERAL_N_MAX = 5000
"""Where that search stops."""


@dataclass(frozen=True, slots=True)
class Config(BaseConfig):
    """What the solver benchmark measures, and how hard.

    Attributes
    ----------
    error_sizes, error_stiffnesses : tuple
        The (N, a) grid of the error study (fig. 2).
    timing_sizes : tuple of int
        N of the timing study (fig. 4), closed chain, a = 10.
    open_sizes : tuple of int
        N at which the open chain is timed with ``"exact"``.
    limits : Mapping[str, int]
        Largest N timed per method (absent: no limit).
    budget : float
        Seconds of timed calls aimed at per measurement.
    min_repeats, max_repeats : int
        Bounds on the number of timed repeats (the median is reported).
    import_runs : int
        Fresh interpreters started to time ``import engine``.
    """

    error_sizes: tuple[int, ...]
    error_stiffnesses: tuple[float, ...]
    timing_sizes: tuple[int, ...]
    open_sizes: tuple[int, ...]
    limits: Mapping[str, int]
    budget: float
    min_repeats: int
    max_repeats: int
    import_runs: int


FULL = Config(
    name="full",
    error_sizes=(50, 100, 200, 500, 1000, 2000),
    error_stiffnesses=(1.0, 10.0, 100.0),
    timing_sizes=(
        100,
        300,
        1000,
        3000,
        5000,
        10_000,
        20_000,
        50_000,
        100_000,
        200_000,
        500_000,
        1_000_000,
    ),
    open_sizes=(1000, 10_000, 100_000, 1_000_000),
    limits={"dmma": 3000, "dmmat": 3000, "efdm": 20_000},
    budget=1.0,
    min_repeats=3,
    max_repeats=51,
    import_runs=5,
)
QUICK = Config(
    name="quick",
    error_sizes=(50, 100, 200, 500),
    error_stiffnesses=(1.0, 10.0, 100.0),
    timing_sizes=(100, 300, 1000, 3000, 5000, 10_000, 20_000),
    open_sizes=(1000, 20_000),
    limits={"dmma": 1000, "dmmat": 1000, "efdm": 5000},
    budget=0.2,
    min_repeats=3,
    max_repeats=15,
    import_runs=3,
)


@dataclass(frozen=True, slots=True)
class Goal:
    """A speed goal: ``fast`` must beat ``slow`` by ``target`` times at N nodes."""

    n: int
    fast: str
    slow: str
    target: float


GOALS = (
    Goal(1_000_000, "exact", "fft", 4.0),
    Goal(20_000, "exact", "fft", 2.0),
    Goal(5000, "efdmt", "efdm", 20.0),
)
IMPORT_GOAL_SECONDS = 0.5
