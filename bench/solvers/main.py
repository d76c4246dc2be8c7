"""Solver benchmark: section IV of Krinidis & Pitas on this machine.

Reproduces the paper's fig. 2 (error of EFDM, EFDMT and DMMAT against DMMA,
eq. 23) and fig. 4 (time per deformation against the number of nodes N), adds
the O(N) ``"exact"`` solver and a plain numpy FFT solve as baselines, shows the
paper's eq. 18 as printed breaking down, and checks the project's speed goals.

Run ``python -m bench.solvers`` (``make bench-solvers``); ``--quick`` runs a
reduced set for smoke tests, ``--out DIR`` changes where the results go
(default ``bench/results/``): ``solvers.md``, ``solvers.json``,
``solvers.png`` (fig. 4) and ``solvers_error.png`` (fig. 2).
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from bench.common import machine
from bench.common.benchmark import Benchmark
from bench.common.log import log
from bench.solvers.config import FULL, LITERAL_STIFFNESSES, QUICK, Config
from bench.solvers.plots import plot_errors, plot_timings
from bench.solvers.report import fmt_seconds, render
from bench.solvers.results import Results, to_json
from bench.solvers.studies import (
    error_study,
    first_call_study,
    goal_study,
    import_study,
    literal_breakdown,
    literal_study,
    time_first_exact_call,
    timing_study,
)


def machine_info() -> dict[str, str]:
    """Platform, CPU and library versions, and the date."""
    affinity = getattr(os, "sched_getaffinity", None)
    usable = str(len(affinity(0))) if affinity is not None else "?"
    return machine.machine_info(("scipy", "numba"), usable_cpus=usable)


def run(config: Config, args: argparse.Namespace) -> Results:
    """Run every study of ``config``."""
    start = time.perf_counter()
    in_process = time_first_exact_call()
    log(f"first exact call in this process: {fmt_seconds(in_process)}")
    imports = import_study(config)
    first_call = first_call_study(in_process)
    errors = error_study(config)
    literal = literal_study()
    breakdown: dict[str, int | None] = {f"{a:g}": literal_breakdown(a) for a in LITERAL_STIFFNESSES}
    log(f"literal eq. 18 breaks down at {breakdown}")
    goals = goal_study(config)
    timings = timing_study(config)
    return Results(
        config=config,
        machine=machine_info(),
        first_call=first_call,
        errors=errors,
        literal=literal,
        literal_breakdown=breakdown,
        timings=timings,
        goals=goals,
        imports=imports,
        wall_seconds=time.perf_counter() - start,
    )


def figures(results: Results, out: Path) -> list[str]:
    """Fig. 4 (``solvers.png``) and fig. 2 (``solvers_error.png``)."""
    plot_timings(results.timings, out / "solvers.png")
    plot_errors(results.errors, out / "solvers_error.png")
    return ["solvers.png", "solvers_error.png"]


BENCHMARK = Benchmark("solvers", __doc__, FULL, QUICK, run, render, to_json, figures=figures)
