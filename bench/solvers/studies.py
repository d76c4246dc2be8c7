"""The solver benchmark's studies: fig. 4 timings, goals, imports, first calls, fig. 2 errors."""

from __future__ import annotations

import os
import tempfile

import numpy as np

import engine
from bench.common.log import log
from bench.common.processes import run_python
from bench.common.timing import measure, measure_side_by_side, sample
from bench.solvers.config import (
    A_MAIN,
    EFDMT_TOL,
    GOALS,
    LITERAL_CASES,
    LITERAL_N_MAX,
    TIMED_METHODS,
    Config,
)
from bench.solvers.problem import (
    Array,
    fft_solve,
    literal_solve,
    make_forces,
    percent_error,
    solver,
)
from bench.solvers.report import fmt_pct, fmt_seconds
from bench.solvers.results import (
    ErrorRecord,
    FirstCall,
    GoalResult,
    ImportResult,
    LiteralRecord,
    TimingRecord,
)

IMPORT_SNIPPET = (
    "import json, sys, time; t = time.perf_counter(); import engine; "
    "dt = time.perf_counter() - t; "
    "print(json.dumps({'seconds': dt, 'loaded': sorted(m for m in "
    "('fastapi', 'uvicorn', 'numba', 'scipy', 'matplotlib') if m in sys.modules)}))"
)
FIRST_CALL_SNIPPET = (
    "import json, time; import numpy as np; import engine; F = np.ones((1000, 2)); "
    "t = time.perf_counter(); engine.deform(F, 10.0); t1 = time.perf_counter() - t; "
    "t = time.perf_counter(); engine.deform(F, 10.0); t2 = time.perf_counter() - t; "
    "print(json.dumps({'first': t1, 'second': t2}))"
)


# --------------------------------------------------------------------------- timings


def is_timed(method: str, n: int, config: Config) -> bool:
    """Whether ``method`` is cheap enough to time at N nodes."""
    return n <= config.limits.get(method, n)


def timing_study(config: Config) -> list[TimingRecord]:
    """Fig. 4: time per deformation of every method (closed, a = 10; open: exact)."""
    records: list[TimingRecord] = []
    for n in config.timing_sizes:
        forces = make_forces(n)
        for method in TIMED_METHODS:
            if is_timed(method, n, config):
                timing = measure(solver(method, forces, A_MAIN), config)
                records.append(TimingRecord(method, n, True, timing))
                log(f"time {method:>6} closed N={n:>8}: {fmt_seconds(timing.median)}")
    for n in config.open_sizes:
        timing = measure(solver("exact", make_forces(n), A_MAIN, closed=False), config)
        records.append(TimingRecord("exact", n, False, timing))
        log(f"time  exact   open N={n:>8}: {fmt_seconds(timing.median)}")
    return records


def goal_study(config: Config) -> list[GoalResult]:
    """The speed goals, each pair measured in alternation in this process."""
    results: list[GoalResult] = []
    for goal in GOALS:
        forces = make_forces(goal.n)
        fast, slow = measure_side_by_side(
            [solver(goal.fast, forces, A_MAIN), solver(goal.slow, forces, A_MAIN)], config
        )
        result = GoalResult(goal, fast, slow)
        results.append(result)
        log(f"goal {goal.fast} vs {goal.slow} N={goal.n}: {result.speedup:.1f}x")
    return results


def import_study(config: Config) -> ImportResult:
    """``import engine`` time in fresh interpreters, and which heavy modules it loads."""
    runs = [run_python(IMPORT_SNIPPET) for _ in range(config.import_runs)]
    loaded = sorted({name for run in runs for name in run["loaded"]})
    result = ImportResult(tuple(float(run["seconds"]) for run in runs), tuple(loaded))
    log(f"import engine: median {fmt_seconds(result.median)}, loaded {loaded or 'nothing heavy'}")
    return result


def first_call_study(in_process: float) -> FirstCall:
    """First ``"exact"`` call: numba compiling into an empty cache, then loading it."""
    with tempfile.TemporaryDirectory(prefix="efdm-numba-cache-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cold = run_python(FIRST_CALL_SNIPPET, env)
        warm = run_python(FIRST_CALL_SNIPPET, env)
    result = FirstCall(
        in_process=in_process,
        cold_cache=float(cold["first"]),
        warm_cache=float(warm["first"]),
        after_first=float(warm["second"]),
    )
    log(
        f"first exact call: compile {fmt_seconds(result.cold_cache)}, cached load "
        f"{fmt_seconds(result.warm_cache)}"
    )
    return result


def time_first_exact_call() -> float:
    """Seconds of this process's first ``"exact"`` call (before any other use)."""
    return sample(solver("exact", make_forces(1000), A_MAIN), 1)


# --------------------------------------------------------------------------- errors


def error_record(n: int, a: float) -> ErrorRecord:
    """Every method's eq. 23 error against DMMA at one (N, a)."""
    forces = make_forces(n)
    reference = engine.deform(forces, a, method="dmma")
    results: dict[str, Array] = {
        "efdm": engine.deform(forces, a, method="efdm"),
        "efdmt": engine.deform(forces, a, method="efdmt"),
        "efdmt_tol": engine.deform(forces, a, method="efdmt", tol=EFDMT_TOL),
        "dmmat": engine.deform(forces, a, method="dmmat"),
        "exact": engine.deform(forces, a, method="exact"),
        "fft": fft_solve(forces, a),
        "literal": literal_solve(forces, a),
    }
    errors = {name: percent_error(U, reference) for name, U in results.items()}
    return ErrorRecord(
        n=n,
        a=a,
        m_paper=engine.paper_radius(n, a),
        m_tol=engine.tolerance_radius(a, EFDMT_TOL),
        errors=errors,
    )


def error_study(config: Config) -> list[ErrorRecord]:
    """Fig. 2: errors against DMMA over the (N, a) grid."""
    records: list[ErrorRecord] = []
    for a in config.error_stiffnesses:
        for n in config.error_sizes:
            record = error_record(n, a)
            records.append(record)
            log(
                f"error a={a:g} N={n}: "
                + ", ".join(f"{k}={fmt_pct(v)}" for k, v in record.errors.items())
            )
    return records


def literal_study() -> list[LiteralRecord]:
    """The paper's eq. 18 as printed at a few (N, a), next to the stable EFDM."""
    records: list[LiteralRecord] = []
    for n, a in LITERAL_CASES:
        forces = make_forces(n)
        reference = engine.deform(forces, a, method="dmma")
        literal = literal_solve(forces, a)
        records.append(
            LiteralRecord(
                n=n,
                a=a,
                literal_pct=percent_error(literal, reference),
                efdm_pct=percent_error(engine.deform(forces, a, method="efdm"), reference),
                finite=bool(np.isfinite(engine.literal_kernel(n, a)).all()),
            )
        )
    return records


def literal_breakdown(a: float, n_max: int = LITERAL_N_MAX, rtol: float = 1e-6) -> int | None:
    """Smallest N whose printed eq. 18 weights are non-finite or off by more than ``rtol``."""
    for n in range(3, n_max + 1):
        stable = engine.green_kernel(n, a)
        literal = engine.literal_kernel(n, a)
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(literal - stable) <= rtol * stable)
        if bad.any():
            return n
    return None
